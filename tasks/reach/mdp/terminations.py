"""Reach predicates."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, tcp_pos
from newton_lab.tasks.common.commands import command_point

SUCCESS_RADIUS = 0.02
"""TCP within this distance of the goal [m]."""


@wp.func
def goal_distance(ctx: TaskContext, w: int) -> float:
    """|TCP - goal| [m]."""
    return wp.length(tcp_pos(ctx, w) - command_point(ctx, w))


@wp.func
def reached_goal(ctx: TaskContext, w: int) -> bool:
    """TCP within 2 cm of the goal (episode success)."""
    return goal_distance(ctx, w) < SUCCESS_RADIUS
