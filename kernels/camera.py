"""Camera kernels: view poses from their mount bodies (+ a seeded jitter), seeded per-row shape colours, shape
indices -> segmentation ids.

Vision randomisation draws from a counter-based RNG keyed by (seed, row, episode, what): a row's draw changes only
when its episode counter does and replays exactly for the same seed and episode."""

from __future__ import annotations

import warp as wp

NO_HIT = wp.constant(wp.uint32(0xFFFFFFFF))
"""Shape index ``SensorCamera`` writes where a ray hits nothing."""


JITTER_M = wp.constant(0.01)
"""Largest camera position jitter [m]."""
JITTER_RAD = wp.constant(0.017453292519943295)
"""Largest camera rotation jitter [rad] (1 deg)."""
HUE_JITTER = wp.constant(0.2)
"""Largest relative change of each colour channel of an object that keeps its hue (``EntityCfg.keep_hue``)."""


@wp.func
def draw(seed: int, row: int, episode: int, what: int) -> wp.uint32:
    """RNG state for draw ``what`` of ``row``'s episode ``episode`` under ``seed`` (counter based: no state kept)."""
    return wp.rand_init(seed, (row * 1000003 + episode) * 64 + what)


@wp.kernel
def mount_transforms(
    body_q: wp.array(dtype=wp.transform),
    view_body: wp.array(dtype=int),
    view_offset: wp.array(dtype=wp.transform),
    view_world: wp.array(dtype=wp.int32),
    episode: wp.array(dtype=int),
    params: wp.array(dtype=int),
    camera0: int,
    out: wp.array(dtype=wp.transformf),
):
    """View ``v``'s camera pose in the world: its mount body's pose (``body_q[view_body[v]]``, global body index)
    times the camera's fixed offset in that body (pinhole frame: looks along -z, +y up), times, when
    ``params[0]`` (randomise) is set, a jitter in the camera frame drawn per (``params[1]`` seed, row, episode,
    camera ``camera0 + v // N``): <= ``JITTER_M`` [m] and <= ``JITTER_RAD`` [rad]."""
    v = wp.tid()
    xf = wp.transform_multiply(body_q[view_body[v]], view_offset[v])
    if params[0] != 0:
        w = int(view_world[v])
        rng = draw(params[1], w, episode[w], 32 + camera0 + v // episode.shape[0])
        p = wp.sample_unit_sphere_surface(rng) * (JITTER_M * wp.randf(rng))
        axis = wp.sample_unit_sphere_surface(rng)
        q = wp.quat_from_axis_angle(axis, JITTER_RAD * wp.randf(rng))
        xf = wp.transform_multiply(xf, wp.transform(p, q))
    out[v] = xf


@wp.kernel
def shape_colors(
    base: wp.array(dtype=wp.vec3),
    shape_world: wp.array(dtype=wp.int32),
    shape_to_id: wp.array(dtype=wp.int32),
    first_robot_id: int,
    keep_hue: wp.array(dtype=wp.int32),
    episode: wp.array(dtype=int),
    params: wp.array(dtype=int),
    out: wp.array(dtype=wp.vec3),
):
    """Shape colours (sRGB in [0, 1]): the model's (``base``) when ``params[0]`` is 0 or the shape is global (the
    ground); else per (seed ``params[1]``, row, episode): every object and the table (segmentation ids 2 ..
    ``first_robot_id - 1``) a uniform random colour, except ids flagged in ``keep_hue`` (objects named by their
    colour), whose model colour only has each channel scaled by [1 - HUE_JITTER, 1 + HUE_JITTER]; and all of the
    row's shapes scaled by one brightness in [0.6, 1.3] (the row's light intensity: Newton's light is global,
    shading per row comes from the albedo)."""
    s = wp.tid()
    w = int(shape_world[s])
    if params[0] == 0 or w < 0:
        out[s] = base[s]
        return
    rng = draw(params[1], w, episode[w], 0)
    gain = 0.6 + 0.7 * wp.randf(rng)
    c = base[s]
    sid = int(shape_to_id[s])
    if sid >= 2 and sid < first_robot_id:
        rc = draw(params[1], w, episode[w], 1 + sid % 31)
        if keep_hue[sid] != 0:
            lo = 1.0 - HUE_JITTER
            c = wp.vec3(
                c[0] * (lo + 2.0 * HUE_JITTER * wp.randf(rc)),
                c[1] * (lo + 2.0 * HUE_JITTER * wp.randf(rc)),
                c[2] * (lo + 2.0 * HUE_JITTER * wp.randf(rc)),
            )
        else:
            c = wp.vec3(0.05 + 0.9 * wp.randf(rc), 0.05 + 0.9 * wp.randf(rc), 0.05 + 0.9 * wp.randf(rc))
    out[s] = wp.vec3(wp.min(c[0] * gain, 1.0), wp.min(c[1] * gain, 1.0), wp.min(c[2] * gain, 1.0))


@wp.kernel
def segmentation_ids(
    shape_index: wp.array(dtype=wp.uint32), shape_to_id: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32)
):
    """Per pixel: the segmentation id of the shape hit (``shape_to_id[shape]``), 0 where nothing is hit."""
    i = wp.tid()
    s = shape_index[i]
    if s == NO_HIT:
        out[i] = 0
    else:
        out[i] = shape_to_id[int(s)]
