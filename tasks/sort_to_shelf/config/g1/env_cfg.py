"""SortToShelf configurations (as on the reference platform): Pick, Nav and Place components and the coherent task, each
for one of the four sorting objects (``task_options={"sorting_object": ...}``, default red_cube).

The Nav and Place components start from per-object scenarios (``scenarios/<component>_<object>.yaml``)
captured at the end of the previous component; the coherent task chains the components without resets.
"""

from __future__ import annotations

from pathlib import Path

from newton_lab.tasks.common import navigation as nav, observations as obs
from newton_lab.tasks.common.config.g1 import cameras, postures
from newton_lab.tasks.common.config.g1.setup import (
    base_actions,
    carried_gripper_closed,
    left_arm_actions,
    shelf_posture,
)
from newton_lab.tasks.common.terminations import dropped, tipped
from newton_lab.tasks.sort_to_shelf import scene
from newton_lab.tasks.sort_to_shelf.mdp import events, rewards, terminations
from newton_lab.tasks.sort_to_shelf.objects import OBJECTS, SortingObject, sorting_object as lookup_object

from newton_lab.task_api.cfg import ActionTermCfg, TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.compose import coherent_task, phase, task_sequence
from newton_lab.task_api.physics import PhysicsCfg

SCENARIOS = Path(__file__).parent / "scenarios"
NAV_SUCCESS_RADIUS = 0.02


def _dropped(obj: SortingObject) -> TerminationTermCfg:
    return TerminationTermCfg(func=dropped, params={"entity": obj.name, "below_z": terminations.DROP_Z})


PHYSICS = PhysicsCfg()
"""The physics of every component and the coherent task: the default solver and no contact filter (no filter or
iteration cap gained anything on an H100; benchmarks history, "Per-task physics settings"); expert peaks: 18
contacts, 61 constraint rows per world (Newton's default capacities: 48 contacts, 64 rows)."""


def _world(obj: SortingObject, **fields) -> TaskCfg:
    base = dict(
        entities=scene.SCENE.entities,
        actions=left_arm_actions(),
        observations=obs.manipulation_observations(object_pose=obs.pose_of(obj.name)),
        phase_success=[],
        terminations={"object_dropped": _dropped(obj)},
        signals={
            "grasped_object": TermCfg(func=terminations.grasped_object(obj)),
            # how far a failed place got: the object let go inside its cell (then knocked out, or not)
            "released_in_cell": TermCfg(func=terminations.released_in_cell(obj)),
        },
        posture=shelf_posture(),
        root_pos=scene.ROBOT_ROOT,
        arm_home=postures.CARRY_LEFT_ARM,
        fixed_base=True,
        physics=PHYSICS,
        cameras=cameras.front_head_rgb_depth_segmentation(),
    )
    base.update(fields)
    return TaskCfg(**base)


def _scenario(component: str, obj: SortingObject, init_scenario: str | None) -> str:
    return init_scenario or str(SCENARIOS / f"{component}_{obj.name}.yaml")


def pick_cfg(sorting_object: str | None = None) -> TaskCfg:
    """Pick the object from the table into the ready posture (success: lifted and arm at ready)."""
    obj = lookup_object(sorting_object)
    terms = {"object_dropped": _dropped(obj)}
    if obj.upright_min > 0:
        terms["object_tipped"] = TerminationTermCfg(func=tipped, params={"entity": obj.name})
    return _world(
        obj,
        phase_success=[terminations.held_at_carry(obj)],
        terminations=terms,
        events={"permute_objects": TermCfg(func=events.permute_objects, params={"objects": tuple(OBJECTS)})},
        rewards=rewards.pick_rewards(obj),
        options={"sorting_object": obj.name},
    )


def nav_cfg(sorting_object: str | None = None, init_scenario: str | None = None) -> TaskCfg:
    """Drive to the object's place position, lift the legs for the upper row, bring the arm to the place-start
    posture (success: all of it held for 20 steps)."""
    obj = lookup_object(sorting_object)
    return _world(
        obj,
        actions=base_actions()
        + [
            ActionTermCfg(name="leg_action", group="legs", type="absolute"),
            ActionTermCfg(name="arm_action", group="left_arm", type="absolute"),
        ],
        observations=nav.nav_observations(obj.place_base_xy),
        phase_success=[terminations.held_at_place_start(obj)],
        rewards=nav.nav_rewards(obj.place_base_xy, NAV_SUCCESS_RADIUS),
        scenario=_scenario("nav", obj, init_scenario),
        initial_targets=carried_gripper_closed(),
        fixed_base=False,
        options={"sorting_object": obj.name},
    )


def place_cfg(sorting_object: str | None = None, init_scenario: str | None = None) -> TaskCfg:
    """Put the object in its cell, let go and retract the arm (success: ``placed``)."""
    obj = lookup_object(sorting_object)
    return _world(
        obj,
        phase_success=[terminations.placed(obj)],
        rewards=rewards.place_rewards(obj),
        scenario=_scenario("place", obj, init_scenario),
        initial_targets=carried_gripper_closed(),
        options={"sorting_object": obj.name},
    )


def coherent_cfg(sorting_object: str | None = None) -> TaskCfg:
    """Pick -> Nav -> Place in one episode; the pick phase holds the base still."""
    obj = lookup_object(sorting_object)
    return coherent_task(
        phases=task_sequence(
            phase("pick", "GalbotG1-SortToShelf-Pick-v0", terms=("left_arm", "left_gripper"), fixed_base=True),
            phase("nav", "GalbotG1-SortToShelf-Nav-v0", terms=("base", "legs", "left_arm")),
            phase("place", "GalbotG1-SortToShelf-Place-v0", terms=("left_arm", "left_gripper")),
        ),
        options={"sorting_object": obj.name},
        actions=[
            ActionTermCfg(name="base_action", group="base", type="velocity"),  # no wheel clip (reference)
            ActionTermCfg(name="leg_action", group="legs", type="absolute"),
            ActionTermCfg(name="arm_action", group="left_arm", type="absolute"),
            ActionTermCfg(name="gripper_action", group="left_gripper", type="binary"),
        ],
        rewards=rewards.coherent_rewards(obj),
    )
