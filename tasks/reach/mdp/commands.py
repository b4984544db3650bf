"""Reach goal command: a TCP position in the robot base frame, written per row at reset."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, base_pose2d

DEFAULT_GOAL_B = wp.constant(wp.vec3(0.45, 0.18, 0.58))
"""Reference goal, base frame [m]."""
GOAL_X_RANGE_B = wp.constant(wp.vec2(0.35, 0.60))
GOAL_Y_RANGE_B = wp.constant(wp.vec2(-0.05, 0.35))
GOAL_Z_RANGE_B = wp.constant(wp.vec2(0.25, 0.55))
"""Randomised goal box, base frame [m]: the upstream box (x 0.35..0.65, y -0.2..0.2, z 0.15..0.5)
shifted toward the left arm so that every goal is reachable with a top-down TCP."""


GOAL_DIM = 3
"""The command is the goal position (x, y, z), world frame [m]: ``TaskCfg.command_dim``."""


@wp.func
def goal(ctx: TaskContext, w: int) -> wp.vec3:
    """Row ``w``'s goal position, world frame [m] (the whole command)."""
    return wp.vec3(ctx.command[w, 0], ctx.command[w, 1], ctx.command[w, 2])


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
    world = wp.vec3(b[0] + c * g[0] - s * g[1], b[1] + s * g[0] + c * g[1], g[2])
    for i in range(GOAL_DIM):
        ctx.command[w, i] = world[i]
