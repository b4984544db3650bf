"""Camera kernels: view poses from their mount bodies, shape indices -> segmentation ids."""

from __future__ import annotations

import warp as wp

NO_HIT = wp.constant(wp.uint32(0xFFFFFFFF))
"""Shape index ``SensorCamera`` writes where a ray hits nothing."""


@wp.kernel
def mount_transforms(
    body_q: wp.array(dtype=wp.transform),
    view_body: wp.array(dtype=int),
    view_offset: wp.array(dtype=wp.transform),
    out: wp.array(dtype=wp.transformf),
):
    """View ``v``'s camera pose in the world: its mount body's pose (``body_q[view_body[v]]``, global body index)
    times the camera's fixed offset in that body (pinhole frame: looks along -z, +y up)."""
    v = wp.tid()
    out[v] = wp.transform_multiply(body_q[view_body[v]], view_offset[v])


@wp.kernel
def segmentation_ids(
    shape_index: wp.array(dtype=wp.uint32),
    shape_to_id: wp.array(dtype=wp.int32),
    out: wp.array(dtype=wp.int32),
):
    """Per pixel: the segmentation id of the shape hit (``shape_to_id[shape]``), 0 where nothing is hit."""
    i = wp.tid()
    s = shape_index[i]
    if s == NO_HIT:
        out[i] = 0
    else:
        out[i] = shape_to_id[int(s)]
