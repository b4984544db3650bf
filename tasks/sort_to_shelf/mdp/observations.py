"""SortToShelf observation terms."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pose, write_transform

from ..objects import SortingObject
from ..scene import OBJECT_SLOT


def make_object_pose(obj: SortingObject):
    """Pose (7) of the object being sorted: x, y, z, qx, qy, qz, qw, env frame."""
    k = OBJECT_SLOT[obj.name]

    @wp.func
    def object_pose(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        write_transform(out, w, col, entity_pose(ctx, w, k))

    return object_pose
