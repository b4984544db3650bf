"""LiftCube dense reward (ManiSkill PickCube-v1 style; the expert and Mimic ignore it).

Three stages, each worth 1/3 (``tasks.common.rewards``; the step reward is in [0, 1], 1 while the success
condition holds): reaching (``1 - tanh(5 |TCP - cube|)`` until the TCP is within 6 cm), grasping (cube in the
closed gripper), lifting (``1 - tanh(5 dz)`` while grasped, dz = height still to go to 10 cm above the
resting height [m]; done when lifted and grasped).
"""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos
from newton_lab.tasks.common.rewards import Stage, closeness, reach_stage, staged_rewards

from ..scene import CUBE
from .terminations import LIFTED_Z, grasped_cube


@wp.func
def lifted_and_grasped(ctx: TaskContext, w: int) -> bool:
    """The success condition at this step (success also needs it held 5 steps)."""
    return entity_pos(ctx, w, CUBE)[2] >= LIFTED_Z and grasped_cube(ctx, w)


@wp.func
def lift_shaping(ctx: TaskContext, w: int) -> float:
    """``1 - tanh(5 dz)``, dz = max(0, 0.225 - cube z) [m]: 0.54 at rest, 1 at the lift height."""
    return closeness(wp.max(LIFTED_Z - entity_pos(ctx, w, CUBE)[2], 0.0))


def dense_rewards():
    """The LiftCube reward terms (weights 1/3 each, sum in [0, 1])."""
    return staged_rewards(
        reach_stage(CUBE),
        Stage("grasping", grasped_cube),
        Stage("lifting", lifted_and_grasped, lift_shaping),
    )
