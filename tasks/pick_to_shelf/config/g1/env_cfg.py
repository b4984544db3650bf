"""PickToShelf configurations (as on the reference platform): the Pick, Nav and Place components and the coherent task.

All four share the PickToShelf world; the robot starts at (-1.2, 0, 0) on its wheels, left arm in the carry
posture. The Nav and Place components start from scenarios (``scenarios/*.yaml``) captured at the end of the
previous component with ``--save-end-scenario``; the coherent task chains the components without resets.
Every term is a generic one (``tasks.common``) with the reference's thresholds.

Dense rewards (ManiSkill PickCube-v1 style, each in [0, 1]): Pick: reaching, grasping, lifting (to z 0.465 m
while grasped), carrying (``1 - tanh(|q_arm - carry|)``, rad): 1/4 each. Place: grasping, placing (``1 -
tanh(5 |bar - resting pose on the deck|)`` while grasped, done when it stands there), releasing (gripper
openness, done with the gripper open; the 20-step hold is not required): 1/3 each. Coherent task: ``(phase +
r_phase) / 3`` with the pick, drive (to the nav goal, yaw not required) and place rewards.
"""

# The tutorial lists parts of this file at the docs site's column width (about 85 characters): the formatter
# leaves them.
# fmt: off
from __future__ import annotations

import math
from pathlib import Path

from newton_lab.tasks.common import navigation as nav, observations as obs
from newton_lab.tasks.common.config.g1 import cameras, postures
from newton_lab.tasks.common.config.g1.setup import (
    base_actions,
    carried_gripper_closed,
    left_arm_actions,
    shelf_posture,
)
from newton_lab.tasks.common.events import randomize_position
from newton_lab.tasks.common.rewards import (
    Stage,
    drive_stage,
    gripper_openness,
    phased_rewards,
    pick_to_carry_stages,
    place_shaping,
    staged_rewards,
)
from newton_lab.tasks.common.terminations import (
    all_of,
    arm_at_home,
    dropped,
    grasped,
    gripper_open,
    held,
    holding,
    lifted,
    resting_on,
    tipped,
    upright,
)
from newton_lab.tasks.pick_to_shelf.scene import BAR_POS, ROBOT_ROOT, SCENE

from newton_lab.task_api.cfg import TaskCfg, TermCfg, TerminationTermCfg
from newton_lab.task_api.compose import coherent_task, phase, task_sequence
from newton_lab.task_api.experts import NavExpert
from newton_lab.task_api.physics import PhysicsCfg

NAV_GOAL_XY = (-1.7, -1.15)
"""Base goal in front of the shelf: deck front edge + 0.65 m [m]."""
NAV_GOAL_YAW = -1.5707963267948966
NAV_SUCCESS_RADIUS = 0.02
SCENARIOS = Path(__file__).parent / "scenarios"

CARRY_MIN_Z = 0.465
"""Pick success: bar centre at or above table top 0.325 + half height 0.08 + lift 0.06 [m] ..."""
CARRY_ARM_TOL = 0.12
"""... and every left-arm joint within this of the carry posture [rad] ..."""
CARRY_HOLD = 10
"""... for this many consecutive steps (demos then show the arm settling inside the band)."""
SHELF_DZ = 0.095
"""The bar stands on the deck: its centre this far above the deck's (deck half 0.015 + bar half 0.08) [m]."""
PLACE_HOLD_STEPS = 20
"""Place success holds this many consecutive steps."""

grasped_bar = grasped(entity="bar")
at_carry = all_of(terms=(lifted(entity="bar", min_z=CARRY_MIN_Z), arm_at_home(tol=CARRY_ARM_TOL)))
bar_on_shelf = all_of(terms=(resting_on(entity="bar", target="shelf_deck", height=SHELF_DZ, xy_tol=0.10, z_tol=0.04),
                             upright(entity="bar", min_up_dot=0.90)))
bar_released_on_shelf = all_of(terms=(bar_on_shelf, gripper_open(tol=0.05)))
goal_reached = nav.goal_reached(goal_xy=NAV_GOAL_XY, radius=NAV_SUCCESS_RADIUS)


PHYSICS = PhysicsCfg()
"""The physics of every component and the coherent task: the default solver and no contact filter (no filter or
iteration cap gained anything on an H100; benchmarks history, "Per-task physics settings"); expert peaks: 12
contacts, 43 constraint rows per world (Newton's default capacities: 48 contacts, 64 rows)."""


def _world(**fields) -> TaskCfg:
    base = dict(
        entities=SCENE.entities,
        actions=left_arm_actions(),
        observations=obs.manipulation_observations(bar_pose=obs.pose_of("bar")),
        phase_success=[],
        terminations={"bar_dropped": TerminationTermCfg(func=dropped, params={"entity": "bar", "below_z": 0.2}),
                      "bar_tipped": TerminationTermCfg(func=tipped, params={"entity": "bar"})},
        signals={"grasped_bar": TermCfg(func=grasped_bar)},
        posture=shelf_posture(),
        root_pos=ROBOT_ROOT,
        arm_home=postures.CARRY_LEFT_ARM,
        fixed_base=True,
        physics=PHYSICS,
        cameras=cameras.front_head_rgb(),
    )
    base.update(fields)
    return TaskCfg(**base)


def pick_rewards():
    """PickToShelf-Pick: reach, grasp, lift, carry posture (1/4 each)."""
    return staged_rewards(*pick_to_carry_stages(entity="bar", rest_z=BAR_POS[2], lift_z=CARRY_MIN_Z, at_carry=at_carry))


def place_rewards():
    """PickToShelf-Place: hold, place on the deck, release (1/3 each)."""
    return staged_rewards(
        Stage("grasping", holding(entity="bar")),
        Stage("placing", bar_on_shelf, place_shaping(entity="bar", target="shelf_deck", offset=(0.0, 0.0, SHELF_DZ))),
        Stage("releasing", bar_released_on_shelf, gripper_openness),
    )


def pick_cfg() -> TaskCfg:
    """Pick the bar from the table and bring it to the carry posture (success: ``at_carry`` held 10 steps)."""
    return _world(phase_success=[held(term=at_carry, steps=CARRY_HOLD)], rewards=pick_rewards(),
                  events={"randomize_bar_position": TermCfg(func=randomize_position, params={
                      "entity": "bar", "x_range": (-0.58, -0.42), "y_range": (0.10, 0.30), "z": BAR_POS[2]})})


def nav_cfg(init_scenario: str | None = None) -> TaskCfg:
    """Drive with the bar in hand to the shelf (success: base within 2 cm of the goal; yaw not checked)."""
    return _world(
        actions=base_actions(),
        observations=nav.nav_observations(NAV_GOAL_XY),
        phase_success=[goal_reached],
        rewards=nav.nav_rewards(NAV_GOAL_XY, NAV_SUCCESS_RADIUS),
        signals={"goal_reached": TermCfg(func=goal_reached)},
        scenario=init_scenario or str(SCENARIOS / "nav_default.yaml"),
        initial_targets=carried_gripper_closed(),
        fixed_base=False,
    )


def place_cfg(init_scenario: str | None = None) -> TaskCfg:
    """Put the bar upright on the shelf deck and let go (success: released on the deck, held 20 steps)."""
    return _world(
        phase_success=[held(term=bar_released_on_shelf, steps=PLACE_HOLD_STEPS)],
        rewards=place_rewards(),
        scenario=init_scenario or str(SCENARIOS / "place_default.yaml"),
        initial_targets=carried_gripper_closed(),
    )


def coherent_cfg() -> TaskCfg:
    """Pick -> Nav -> Place in one episode; the episode succeeds when the bar stands on the shelf."""
    drive = staged_rewards(drive_stage(goal_xy=NAV_GOAL_XY, goal_yaw=NAV_GOAL_YAW, radius=NAV_SUCCESS_RADIUS,
                                       yaw_tol=math.pi))
    return coherent_task(
        phases=task_sequence(
            phase("pick", "GalbotG1-PickToShelf-Pick-v0", terms=("left_arm", "left_gripper")),
            phase("nav", "GalbotG1-PickToShelf-Nav-v0", terms=("base",)),
            phase("place", "GalbotG1-PickToShelf-Place-v0", terms=("left_arm", "left_gripper")),
        ),
        rewards=phased_rewards([("pick", pick_rewards()), ("nav", drive), ("place", place_rewards())]),
    )


def nav_expert(init_scenario: str | None = None) -> NavExpert:
    """PickToShelf-Nav expert: turn to face the shelf, then drive straight to the goal."""
    return NavExpert(goal=NAV_GOAL_XY, goal_yaw=NAV_GOAL_YAW, success_radius=NAV_SUCCESS_RADIUS, yaw_tolerance=0.03,
                     rotate_before_translate=True, waypoint_spacing=10.0)
