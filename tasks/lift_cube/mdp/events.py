"""LiftCube reset events."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, set_entity_pose

from ..scene import CUBE, CUBE_INIT

CUBE_X_RANGE = wp.constant(wp.vec2(-0.38, -0.22))
"""Cube x at reset, env frame [m]."""
CUBE_Y_RANGE = wp.constant(wp.vec2(0.08, 0.26))
"""Cube y at reset, env frame [m]."""
CUBE_Z = wp.constant(CUBE_INIT[2])


@wp.func
def randomize_cube(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
    """Cube x, y uniform in the ranges above, yaw 0, when randomising."""
    if not randomize:
        return
    rng = wp.rand_init(seed, stream)
    x = wp.randf(rng, CUBE_X_RANGE[0], CUBE_X_RANGE[1])
    y = wp.randf(rng, CUBE_Y_RANGE[0], CUBE_Y_RANGE[1])
    set_entity_pose(ctx, w, CUBE, wp.vec3(x, y, CUBE_Z), wp.quat_identity())
