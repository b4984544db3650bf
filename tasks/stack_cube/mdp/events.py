"""StackCube reset event: three cubes placed apart on the table (this task's own sampler)."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, set_entity_pose

from newton_lab.task_api.terms import term_factory

# The reference samples x in (-0.35, -0.25), y in (0.14, 0.23) with a 0.09 m minimum separation: only
# 2e-5 of joint draws are valid there, so its 5000-try sampler returns overlapping cubes ~90 % of the
# time. The region is widened just enough that valid layouts are 12 % of draws (never exhausted).
X_RANGE = wp.constant(wp.vec2(-0.40, -0.20))
Y_RANGE = wp.constant(wp.vec2(0.10, 0.26))
YAW_RANGE = wp.constant(wp.vec2(-1.0, 1.0))
CUBE_Z = 0.125
MIN_SEPARATION = 0.09
"""Smallest centre distance between two cubes [m]."""
MAX_TRIES = 5000
CUBE_SIZE = 0.05
"""Edge of a cube [m]: a pre-stacked cube sits this far above the one below."""


@term_factory(entities=("cubes",))
def randomize_cube_positions(*, cubes: tuple[int, int, int], prestacked: bool = False, turned: bool = True):
    """Rejection-sample the three ``cubes``' positions at least 0.09 m apart, each with a random yaw in ``YAW_RANGE``
    (``turned``; else yaw 0, the positions unchanged). With ``prestacked`` the second cube is then set on the first
    (same yaw), as the first stacking subtask leaves it: the start of the second subtask on its own (the draws are
    those of the unstacked layout)."""
    slots = wp.vec3i(*cubes)
    on_first = bool(prestacked)
    yaw_scale = 1.0 if turned else 0.0

    @wp.func
    def place_three_cubes_apart(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
        if not randomize:
            return
        rng = wp.rand_init(seed, stream)
        p0 = wp.vec2(0.0, 0.0)
        p1 = wp.vec2(0.0, 0.0)
        p2 = wp.vec2(0.0, 0.0)
        for _ in range(MAX_TRIES):
            p0 = wp.vec2(wp.randf(rng, X_RANGE[0], X_RANGE[1]), wp.randf(rng, Y_RANGE[0], Y_RANGE[1]))
            p1 = wp.vec2(wp.randf(rng, X_RANGE[0], X_RANGE[1]), wp.randf(rng, Y_RANGE[0], Y_RANGE[1]))
            p2 = wp.vec2(wp.randf(rng, X_RANGE[0], X_RANGE[1]), wp.randf(rng, Y_RANGE[0], Y_RANGE[1]))
            if (
                wp.length(p0 - p1) >= MIN_SEPARATION
                and wp.length(p1 - p2) >= MIN_SEPARATION
                and wp.length(p0 - p2) >= MIN_SEPARATION
            ):
                break
        ps = wp.mat33(p0[0], p0[1], 0.0, p1[0], p1[1], 0.0, p2[0], p2[1], 0.0)
        first = wp.quat_identity()
        for i in range(3):
            yaw = wp.randf(rng, YAW_RANGE[0], YAW_RANGE[1]) * yaw_scale
            q = wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), yaw)
            pos = wp.vec3(ps[i, 0], ps[i, 1], CUBE_Z)
            if i == 0:
                first = q
            if on_first and i == 1:
                pos = wp.vec3(ps[0, 0], ps[0, 1], CUBE_Z + CUBE_SIZE)
                q = first
            set_entity_pose(ctx, w, slots[i], pos, q)

    return place_three_cubes_apart
