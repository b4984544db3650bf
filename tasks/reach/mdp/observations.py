"""Reach observations."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, write_vec3

from .commands import goal


@wp.func
def pose_command(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Goal position (3), world frame [m]."""
    write_vec3(out, w, col, goal(ctx, w))
