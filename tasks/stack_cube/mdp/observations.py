"""StackCube object observations (world frame)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pose, entity_pos, write_vec3

from ..scene import CUBE_1


@wp.func
def cube_positions(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Centres of cube_1..3 (9)."""
    for i in range(3):
        write_vec3(out, w, col + 3 * i, entity_pos(ctx, w, CUBE_1 + i))


@wp.func
def cube_orientations(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Quaternions of cube_1..3, xyzw (12)."""
    for i in range(3):
        q = wp.transform_get_rotation(entity_pose(ctx, w, CUBE_1 + i))
        for j in range(4):
            out[w, col + 4 * i + j] = q[j]
