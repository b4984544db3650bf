"""PickCube object observations."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pose, entity_pos, write_transform, write_vec3

from ..scene import BLUE_BLOCK, CUBE


@wp.func
def cube_pose(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Cube pose (7), world frame."""
    write_transform(out, w, col, entity_pose(ctx, w, CUBE))


@wp.func
def blue_block_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Blue block centre (3), world frame."""
    write_vec3(out, w, col, entity_pos(ctx, w, BLUE_BLOCK))
