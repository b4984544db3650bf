"""PickToShelf reset events."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, set_entity_pose

from ..scene import BAR_POS, CUBE

BAR_Z = BAR_POS[2]
"""Bar centre height on the table [m]."""


@wp.func
def randomize_bar_position(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
    """Bar at x in (-0.58, -0.42), y in (0.10, 0.30), upright, yaw 0 (only when randomising)."""
    if not randomize:
        return
    rng = wp.rand_init(seed, stream)
    x = wp.randf(rng, -0.58, -0.42)
    y = wp.randf(rng, 0.10, 0.30)
    set_entity_pose(ctx, w, CUBE, wp.vec3(x, y, BAR_Z), wp.quat_identity())
