"""Reach rewards (upstream Reach structure; weights in the env cfg)."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext

from .terminations import SUCCESS_RADIUS, goal_distance


@wp.func
def position_tanh(ctx: TaskContext, w: int) -> float:
    """1 - tanh(d / 0.1)."""
    return 1.0 - wp.tanh(goal_distance(ctx, w) / 0.1)


@wp.func
def position_tanh_fine(ctx: TaskContext, w: int) -> float:
    """1 - tanh(d / 0.02): the term that pays for the last centimetres, at the scale of the success radius (2 cm).
    The reference's two terms (-d and the 0.1 m tanh) differ by under 0.02 a step between 5 cm and 2 cm, and a
    PPO actor settled about 5 cm short of its goals without this term."""
    return 1.0 - wp.tanh(goal_distance(ctx, w) / SUCCESS_RADIUS)


@wp.func
def arm_joint_vel(ctx: TaskContext, w: int) -> float:
    """Sum of squared arm joint velocities [rad^2/s^2]."""
    s = float(0.0)
    for j in range(ctx.arm_coords.shape[0]):
        v = ctx.joint_qd[w * ctx.dofs_per_world + ctx.arm_coords[j]]
        s += v * v
    return s
