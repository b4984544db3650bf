"""PickToShelf dense rewards (ManiSkill PickCube-v1 style, ``tasks.common.rewards``; each in [0, 1]).

Pick: reaching (``1 - tanh(5 |TCP - bar|)`` until within 6 cm), grasping, lifting (``1 - tanh(5 dz)`` while
grasped, dz = height still to go to z 0.465 m), carrying (``1 - tanh(|q_arm - carry|)``, rad, until
``at_carry``): 1/4 each. Place: grasping (the bar in hand), placing (``1 - tanh(5 |bar - resting pose on
the deck|)`` while grasped, done when it stands there), releasing (gripper openness while it stands there,
done with the gripper open = the success condition, whose 20-step hold is not required): 1/3 each.
Coherent task: ``(phase + r_phase) / 3`` with the pick, drive (``1 - tanh(d)`` to the nav goal, d in m, and
``1 - tanh(|yaw error|)``) and place rewards.
"""

from __future__ import annotations

import math

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos, entity_up_dot, gripper_q
from newton_lab.task_api.cfg import RewardTermCfg
from newton_lab.tasks.common.rewards import (
    Stage, closeness, drive_stage, gripper_openness, phased_rewards, pick_to_carry_stages, staged_rewards,
)

from ..scene import CUBE, DECK
from .terminations import (
    CARRY_MIN_Z, GRIPPER_OPEN_TOL, SHELF_DZ, SHELF_DZ_TOL, SHELF_XY_TOL, UPRIGHT_MIN, at_carry, grasped_cube,
)


def pick_rewards() -> dict[str, RewardTermCfg]:
    """PickToShelf-Pick: reach, grasp, lift, carry posture (1/4 each)."""
    return staged_rewards(*pick_to_carry_stages(obj=CUBE, grasped=grasped_cube, lift_z=CARRY_MIN_Z, at_carry=at_carry))


@wp.func
def shelf_error(ctx: TaskContext, w: int) -> float:
    """|bar - (deck centre + (0, 0, 0.095))|: distance from the bar's resting pose on the deck [m]."""
    return wp.length(entity_pos(ctx, w, CUBE) - entity_pos(ctx, w, DECK) - wp.vec3(0.0, 0.0, SHELF_DZ))


@wp.func
def bar_on_shelf(ctx: TaskContext, w: int) -> bool:
    """Bar standing on the deck within the success tolerances, whatever the gripper does."""
    c = entity_pos(ctx, w, CUBE)
    d = entity_pos(ctx, w, DECK)
    ok = wp.length(wp.vec2(c[0] - d[0], c[1] - d[1])) <= SHELF_XY_TOL
    ok = ok and wp.abs(c[2] - (d[2] + SHELF_DZ)) <= SHELF_DZ_TOL
    return ok and entity_up_dot(ctx, w, CUBE) >= UPRIGHT_MIN


@wp.func
def bar_released_on_shelf(ctx: TaskContext, w: int) -> bool:
    """Bar standing on the deck with the gripper open (the Place success condition at this step)."""
    return bar_on_shelf(ctx, w) and wp.abs(gripper_q(ctx, w)) <= GRIPPER_OPEN_TOL


@wp.func
def shelf_shaping(ctx: TaskContext, w: int) -> float:
    """``1 - tanh(5 shelf_error)`` [m -> 0..1] (counted while grasped)."""
    return closeness(shelf_error(ctx, w))


def place_rewards() -> dict[str, RewardTermCfg]:
    """PickToShelf-Place: hold, place on the deck, release (1/3 each)."""
    return staged_rewards(
        Stage("grasping", grasped_cube),
        Stage("placing", bar_on_shelf, shelf_shaping),
        Stage("releasing", bar_released_on_shelf, gripper_openness),
    )


def coherent_rewards(nav_goal_xy: tuple[float, float], nav_goal_yaw: float, nav_radius: float):
    """PickToShelf-v0: pick, drive (base within ``nav_radius`` [m] of ``nav_goal_xy``; yaw not required, as for
    the phase's success), place; ``(phase + r_phase) / 3``."""
    drive = staged_rewards(drive_stage(goal_xy=nav_goal_xy, goal_yaw=nav_goal_yaw, radius=nav_radius,
                                       yaw_tol=math.pi))
    return phased_rewards([("pick", pick_rewards()), ("nav", drive), ("place", place_rewards())])
