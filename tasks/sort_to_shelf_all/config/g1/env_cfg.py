"""SortToShelf-All configurations: the Return component (back from the shelf to the table) and the coherent task
that sorts all four objects in one episode, in a per-episode order.

The coherent task is built here rather than by ``coherent_task``: its phases' predicates are SortToShelf's
per-object ones switched per row on the object the phase acts on (``mdp.terminations.for_target``), which one
component per phase (with one fixed ``sorting_object``) cannot express. Its phases still name SortToShelf's
components, so the split labels every segment with the component it ran, and the experts are theirs.
"""

from __future__ import annotations

from pathlib import Path

from newton_lab.tasks.common import navigation as nav, observations as obs
from newton_lab.tasks.common.config.g1 import cameras, postures
from newton_lab.tasks.common.config.g1.setup import base_actions, shelf_posture
from newton_lab.tasks.sort_to_shelf import scene
from newton_lab.tasks.sort_to_shelf.config.g1.env_cfg import PHYSICS
from newton_lab.tasks.sort_to_shelf.mdp import terminations as one
from newton_lab.tasks.sort_to_shelf.mdp.events import permute_objects
from newton_lab.tasks.sort_to_shelf.objects import OBJECTS, sorting_object as lookup_object

from newton_lab.robots.g1 import spec
from newton_lab.task_api.cfg import ActionTermCfg, PhaseCfg, TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.compose import phase as compose_phase

from ...mdp import events, observations as all_obs, rewards, terminations as terms
from ...order import KINDS, OBJECT_COUNT, PICK, phase_layout

SCENARIOS = Path(__file__).parent / "scenarios"
TABLE_XY = scene.ROBOT_ROOT[:2]
"""Where the robot picks from: its reset position at the table [m]."""
TABLE_LEGS = (0.0,) * len(spec.LEG_JOINTS)
"""Legs down at the table [rad]."""
COMPONENTS = {
    "pick": ("GalbotG1-SortToShelf-Pick-v0", ("left_arm", "left_gripper")),
    "nav": ("GalbotG1-SortToShelf-Nav-v0", ("base", "legs", "left_arm")),
    "place": ("GalbotG1-SortToShelf-Place-v0", ("left_arm", "left_gripper")),
    "return": ("GalbotG1-SortToShelf-Return-v0", ("base", "legs", "left_arm")),
}
"""Phase kind -> (component task, the joint groups it commands)."""
TARGET_OPTION = "sorting_object"
"""The component option that differs per row: the phase's target object (its one-hot observation has this name)."""


def _mobile_actions(*, clip: bool) -> list[ActionTermCfg]:
    return base_actions(clip=clip) + [
        ActionTermCfg(name="leg_action", group="legs", type="absolute"),
        ActionTermCfg(name="arm_action", group="left_arm", type="absolute"),
    ]


def _common(**fields) -> TaskCfg:
    base = dict(
        entities=scene.SCENE.entities,
        terminations={"object_dropped": TerminationTermCfg(func=terms.any_dropped())},
        posture=shelf_posture(),
        root_pos=scene.ROBOT_ROOT,
        arm_home=postures.CARRY_LEFT_ARM,
        physics=PHYSICS,
        cameras=cameras.front_head_rgb_depth_segmentation(),
    )
    base.update(fields)
    return TaskCfg(**base)


def return_cfg(sorting_object: str | None = None, init_scenario: str | None = None) -> TaskCfg:
    """Back from the shelf to the table: legs down, arm at ready, base at its reset position facing the table
    (success: all of it held 20 steps). Alone it starts where SortToShelf-Place's expert left ``sorting_object``
    (``scenarios/return_<object>.yaml``, captured with ``--save-end-scenario``); inside SortToShelf-All, wherever
    the place left the robot."""
    obj = lookup_object(sorting_object)
    return _common(
        actions=_mobile_actions(clip=True),
        observations=nav.nav_observations(TABLE_XY),
        phase_success=[terms.at_table(TABLE_XY, postures.CARRY_LEFT_ARM, TABLE_LEGS)],
        rewards=rewards.return_rewards(TABLE_XY, postures.CARRY_LEFT_ARM, TABLE_LEGS),
        scenario=init_scenario or str(SCENARIOS / f"return_{obj.name}.yaml"),
        fixed_base=False,
        options={TARGET_OPTION: obj.name},
    )


def _phase_success(kind: str):
    if kind == "return":
        return terms.at_table(TABLE_XY, postures.CARRY_LEFT_ARM, TABLE_LEGS)
    return {"pick": terms.picked, "nav": terms.at_place_start, "place": terms.placed}[kind]()


def phase(name: str, task_id: str, *, kind: str) -> PhaseCfg:
    """Phase ``name`` of ``kind`` running component ``task_id`` (its joint groups, base held while picking, the
    per-row target object but while returning)."""
    if COMPONENTS[kind][0] != task_id:
        raise ValueError(f"phase {name!r} of kind {kind!r} runs {COMPONENTS[kind][0]}, not {task_id}")
    return compose_phase(
        name,
        task_id,
        terms=COMPONENTS[kind][1],
        fixed_base=kind == "pick",
        kind=kind,
        target_option=None if kind == "return" else TARGET_OPTION,
    )


def all_cfg() -> TaskCfg:
    """Pick -> nav -> place -> return for each object of the row's order, the last without return (15 phases);
    every object on the table is shuffled over the slots and the order drawn at reset."""
    phases = [
        phase("pick_1", "GalbotG1-SortToShelf-Pick-v0", kind="pick"),
        phase("nav_1", "GalbotG1-SortToShelf-Nav-v0", kind="nav"),
        phase("place_1", "GalbotG1-SortToShelf-Place-v0", kind="place"),
        phase("return_1", "GalbotG1-SortToShelf-Return-v0", kind="return"),
        phase("pick_2", "GalbotG1-SortToShelf-Pick-v0", kind="pick"),
        phase("nav_2", "GalbotG1-SortToShelf-Nav-v0", kind="nav"),
        phase("place_2", "GalbotG1-SortToShelf-Place-v0", kind="place"),
        phase("return_2", "GalbotG1-SortToShelf-Return-v0", kind="return"),
        phase("pick_3", "GalbotG1-SortToShelf-Pick-v0", kind="pick"),
        phase("nav_3", "GalbotG1-SortToShelf-Nav-v0", kind="nav"),
        phase("place_3", "GalbotG1-SortToShelf-Place-v0", kind="place"),
        phase("return_3", "GalbotG1-SortToShelf-Return-v0", kind="return"),
        phase("pick_4", "GalbotG1-SortToShelf-Pick-v0", kind="pick"),
        phase("nav_4", "GalbotG1-SortToShelf-Nav-v0", kind="nav"),
        phase("place_4", "GalbotG1-SortToShelf-Place-v0", kind="place"),
    ]
    if [(p.name, p.kind) for p in phases] != phase_layout():
        raise ValueError(f"SortToShelf-All's phases must follow order.phase_layout(): {phase_layout()}")
    success = {kind: _phase_success(kind) for kind in KINDS}  # one predicate per kind: the kernel inlines it once
    signals = {
        "grasped_object": TermCfg(func=terms.grasped_target()),
        "released_in_cell": TermCfg(func=terms.released_target()),
    }
    # per object, whatever its place in the order: lifted to the ready posture, and let go in its cell
    signals.update({f"picked_{o.name}": TermCfg(func=one.at_carry(o)) for o in OBJECTS.values()})
    signals.update({f"sorted_{o.name}": TermCfg(func=one.released_in_cell(o)) for o in OBJECTS.values()})
    return _common(
        actions=_mobile_actions(clip=False)
        + [ActionTermCfg(name="gripper_action", group="left_gripper", type="binary")],
        observations=obs.manipulation_observations(
            object_pose=all_obs.TARGET_POSE, **{TARGET_OPTION: all_obs.TARGET_ONE_HOT}
        ),
        phase_success=[success[p.kind] for p in phases],
        phases=phases,
        terminations={
            "object_dropped": TerminationTermCfg(func=terms.any_dropped()),
            "object_tipped": TerminationTermCfg(func=terms.target_tipped(PICK)),
        },
        signals=signals,
        rewards=rewards.all_rewards(
            [(p.name, p.kind) for p in phases], rewards.return_rewards(TABLE_XY, postures.CARRY_LEFT_ARM, TABLE_LEGS)
        ),
        events={
            "permute_objects": TermCfg(func=permute_objects, params={"objects": tuple(OBJECTS)}),
            "draw_sort_order": TermCfg(func=events.draw_sort_order),
        },
        command_dim=OBJECT_COUNT,
        fixed_base=False,
        terminate_on_success=True,
    )


if tuple(COMPONENTS) != KINDS:
    raise ValueError(f"COMPONENTS {tuple(COMPONENTS)} must name one component per phase kind {KINDS}")
