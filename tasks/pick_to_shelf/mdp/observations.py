"""PickToShelf observation terms."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pose, write_transform

from ..scene import CUBE


@wp.func
def cube_pose(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Bar pose (7): x, y, z, qx, qy, qz, qw, env frame."""
    write_transform(out, w, col, entity_pose(ctx, w, CUBE))
