"""Reach predicates."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, tcp_pos

SUCCESS_RADIUS = 0.02
"""TCP within this distance of the goal [m]."""


@wp.func
def goal_distance(ctx: TaskContext, w: int) -> float:
    g = wp.vec3(ctx.command[w, 0], ctx.command[w, 1], ctx.command[w, 2])
    return wp.length(tcp_pos(ctx, w) - g)


@wp.func
def reached_goal(ctx: TaskContext, w: int) -> bool:
    return goal_distance(ctx, w) < SUCCESS_RADIUS
