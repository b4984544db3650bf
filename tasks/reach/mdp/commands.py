"""Reach goal command: a TCP position drawn in the robot base frame, written per row at reset as the commanded
point (``tasks.common.commands``)."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, base_pose2d
from newton_lab.tasks.common.commands import set_command_point

DEFAULT_GOAL_B = wp.constant(wp.vec3(0.45, 0.18, 0.58))
"""Reference goal, base frame [m]."""
GOAL_X_RANGE_B = wp.constant(wp.vec2(0.35, 0.60))
GOAL_Y_RANGE_B = wp.constant(wp.vec2(-0.05, 0.35))
GOAL_Z_RANGE_B = wp.constant(wp.vec2(0.25, 0.55))
"""Randomised goal box, base frame [m]: the upstream box (x 0.35..0.65, y -0.2..0.2, z 0.15..0.5)
shifted toward the left arm so that every goal is reachable with a top-down TCP."""


@wp.func
def sample_goal(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
    """The goal: a base-frame point (the default, or uniform in the goal box) turned into the world frame with
    the row's planar base pose."""
    g = DEFAULT_GOAL_B
    if randomize:
        rng = wp.rand_init(seed, stream)
        g = wp.vec3(
            wp.randf(rng, GOAL_X_RANGE_B[0], GOAL_X_RANGE_B[1]),
            wp.randf(rng, GOAL_Y_RANGE_B[0], GOAL_Y_RANGE_B[1]),
            wp.randf(rng, GOAL_Z_RANGE_B[0], GOAL_Z_RANGE_B[1]),
        )
    b = base_pose2d(ctx, w)
    c = wp.cos(b[2])
    s = wp.sin(b[2])
    set_command_point(ctx, w, wp.vec3(b[0] + c * g[0] - s * g[1], b[1] + s * g[0] + c * g[1], g[2]))
