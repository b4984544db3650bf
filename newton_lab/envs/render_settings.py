"""The cameras' render settings: what they draw, the sky, the light, and how Newton's ``SensorCamera`` walks the
pixels (``render_config``; ``Cameras`` renders with it, ``bench --render-orders`` times the alternatives)."""

from __future__ import annotations

import newton
import numpy as np
import warp as wp
from newton.sensors import SensorCamera

DEFAULT_LIGHT_DIRECTION = (-0.5773502691896258, 0.5773502691896258, -0.5773502691896258)
"""Direction the light shines in (world frame, unit; Newton's default for a z-up model): down, from +x and -y."""
SKY_RGBA = (178, 190, 204, 0)
"""Colour where a view ray hits nothing (sRGB bytes; alpha 0: nothing there)."""
RENDERED_SHAPES = newton.ShapeFlags.VISIBLE | newton.ShapeFlags.COLLIDE_SHAPES
"""Shapes the cameras see: visual and collision geometry (the G1 MJCF's collision geoms are its body; Newton
marks them invisible because the MJCF also has visual geoms), not sites, and not the robot links out of every
view (``build_render_bvh``)."""
RENDER_ORDER = SensorCamera.RenderOrder.TILED
"""How the render's threads walk the views' pixels (Newton's ``RenderOrder``; the pixels are the same in every
order, only the speed differs). Tiles of neighbouring pixels of one view: the fastest of the orders that
``newton-lab bench --cameras ... --render-orders`` times on an H200 with the policies' two views at 4096 worlds, ahead
of Newton's default (a pixel of every view, then the next pixel) and of view after view (docs/benchmarks.md, Env
step)."""
RENDER_TILE = (8, 8)
"""Tile width and height [px] of the ``TILED`` order: 8x8 was the fastest tile in both sweeps of the policies' two
views at 4096 worlds on an H200 (2 % ahead of Newton's default 16x8 each time: 184.1 k against 180.0 k env-steps/s
drawing every shape, 250.0 k against 245.2 k with the unseen links left out; docs/results)."""
RENDER_BLOCK_DIM = 64
"""Threads per block of the render's kernel launch (launch-time only; no recompilation)."""


def render_config(
    max_distance: float, order=None, block_dim: int | None = None, tile: tuple[int, int] | None = None
) -> SensorCamera.RenderConfig:
    """The env's render settings: rays end at ``max_distance`` [m]; ``order`` / ``block_dim`` / ``tile`` replace
    ``RENDER_ORDER`` / ``RENDER_BLOCK_DIM`` / ``RENDER_TILE`` (the bench's sweep)."""
    tile_width, tile_height = RENDER_TILE if tile is None else tile
    return SensorCamera.RenderConfig(
        max_distance=max_distance,
        render_order=RENDER_ORDER if order is None else order,
        block_dim=RENDER_BLOCK_DIM if block_dim is None else block_dim,
        tile_width=tile_width,
        tile_height=tile_height,
    )


def build_render_bvh(model: newton.Model, state: newton.State, hidden: np.ndarray) -> None:
    """Build the model's shape BVH, which Newton's ``SensorCamera`` traces its rays through, over the
    ``RENDERED_SHAPES`` less the shapes marked in ``hidden`` (bool per shape of the model): shapes no view sees
    cost every ray that passes their bounds a box test, and draw nothing."""
    # Newton's BVH build selects its shapes by flag alone. It reads ``model.shape_flags`` once, here (refits and
    # renders use the list of shapes it made), so the build reads a copy with the hidden shapes' render flags
    # cleared; the model's own flags, which the collision pipeline reads, are put back at once.
    flags = model.shape_flags
    drawn = flags.numpy().copy()  # on a CPU device numpy() is a view of the model's own flags
    drawn[np.asarray(hidden, dtype=bool)] &= ~int(RENDERED_SHAPES)
    model.shape_flags = wp.array(drawn, dtype=flags.dtype, device=flags.device)
    try:
        model.bvh_build_shapes(state, shape_flags=RENDERED_SHAPES)
    finally:
        model.shape_flags = flags
