"""Reach observations."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext


@wp.func
def pose_command(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Goal position (3), world frame."""
    for i in range(3):
        out[w, col + i] = ctx.command[w, i]
