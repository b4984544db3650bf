"""LiftCube object observations."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pose, write_transform

from ..scene import CUBE


@wp.func
def cube_pose(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Cube pose (7), world frame."""
    write_transform(out, w, col, entity_pose(ctx, w, CUBE))
