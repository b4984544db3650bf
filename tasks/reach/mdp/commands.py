"""Reach goal command: a TCP position in the robot base frame, written per row at reset."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext

DEFAULT_GOAL_B = wp.constant(wp.vec3(0.45, 0.18, 0.58))
"""Reference goal, base frame [m]."""
GOAL_X_RANGE_B = wp.constant(wp.vec2(0.35, 0.60))
GOAL_Y_RANGE_B = wp.constant(wp.vec2(-0.05, 0.35))
GOAL_Z_RANGE_B = wp.constant(wp.vec2(0.25, 0.55))
"""Randomised goal box, base frame [m]: the upstream box (x 0.35..0.65, y -0.2..0.2, z 0.15..0.5)
shifted toward the left arm so that every goal is reachable with a top-down TCP."""


@wp.func
def sample_goal(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
    """Command columns 0..2 = goal position, world frame (base pose from the planar base joints)."""
    g = DEFAULT_GOAL_B
    if randomize:
        rng = wp.rand_init(seed, stream)
        g = wp.vec3(
            wp.randf(rng, GOAL_X_RANGE_B[0], GOAL_X_RANGE_B[1]),
            wp.randf(rng, GOAL_Y_RANGE_B[0], GOAL_Y_RANGE_B[1]),
            wp.randf(rng, GOAL_Z_RANGE_B[0], GOAL_Z_RANGE_B[1]),
        )
    base = w * ctx.coords_per_world
    bx = ctx.joint_q[base + 0]
    by = ctx.joint_q[base + 1]
    yaw = ctx.joint_q[base + 2]
    c = wp.cos(yaw)
    s = wp.sin(yaw)
    ctx.command[w, 0] = bx + c * g[0] - s * g[1]
    ctx.command[w, 1] = by + s * g[0] + c * g[1]
    ctx.command[w, 2] = g[2]
