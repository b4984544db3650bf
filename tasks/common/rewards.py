"""Reward terms shared by the G1 tasks: ``func(ctx, w) -> float``."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext


@wp.func
def action_rate(ctx: TaskContext, w: int) -> float:
    """Sum of squared action changes since the last step."""
    s = float(0.0)
    for j in range(ctx.actions.shape[1]):
        d = ctx.actions[w, j] - ctx.prev_actions[w, j]
        s += d * d
    return s
