"""Reach rewards (upstream Reach structure; weights in the env cfg)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext

from .terminations import goal_distance


@wp.func
def position_tanh(ctx: TaskContext, w: int) -> float:
    """1 - tanh(d / 0.1)."""
    return 1.0 - wp.tanh(goal_distance(ctx, w) / 0.1)


@wp.func
def arm_joint_vel(ctx: TaskContext, w: int) -> float:
    """Sum of squared arm joint velocities [rad^2/s^2]."""
    s = float(0.0)
    for j in range(7):
        v = ctx.joint_qd[w * ctx.dofs_per_world + ctx.arm_coords[j]]
        s += v * v
    return s
