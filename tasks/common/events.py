"""Reset events every table-top task can list, parametrised by name (``@term_factory``)."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, set_entity_pose

from newton_lab.task_api.terms import term_factory


@term_factory(entities=("entity",))
def randomize_position(
    *,
    entity: int,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    z: float,
    yaw_range: tuple[float, float] = (0.0, 0.0),
):
    """When randomising: ``entity`` at x, y uniform in ``x_range``, ``y_range`` [m], centre height ``z`` [m],
    yaw uniform in ``yaw_range`` [rad] (drawn only when the range is not empty; else yaw 0). Env frame."""
    x0, x1 = (float(v) for v in x_range)
    y0, y1 = (float(v) for v in y_range)
    a0, a1 = (float(v) for v in yaw_range)
    z = float(z)
    turn = a1 > a0

    @wp.func
    def randomize_entity_position(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
        if not randomize:
            return
        rng = wp.rand_init(seed, stream)
        x = wp.randf(rng, x0, x1)
        y = wp.randf(rng, y0, y1)
        q = wp.quat_identity()
        if wp.static(turn):
            q = wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), wp.randf(rng, a0, a1))
        set_entity_pose(ctx, w, entity, wp.vec3(x, y, z), q)

    return randomize_entity_position


@wp.func
def reset_position(ctx: TaskContext, w: int, k: int) -> wp.vec3:
    """Where entity ``k`` of row ``w`` starts the episode: a dynamic one's free-joint coordinates as the reset has
    written them so far (the bodies' poses follow only after the events), a static one's fixed pose. Env frame [m]."""
    c = ctx.entity_coord[k]
    if c < 0:
        return wp.transform_get_translation(ctx.entity_static_pose[k])
    base = w * ctx.coords_per_world + c
    return wp.vec3(ctx.joint_q[base], ctx.joint_q[base + 1], ctx.joint_q[base + 2])


@term_factory(entities=("entity", "surface"))
def scatter_on(*, entity: int, surface: int, count: int, margin: float = 0.04, gap: float = 0.03, tries: int = 32):
    """At every reset, randomising or not (the draws are the row's seeded stream): ``entity`` upright at a spot
    drawn uniformly on the top of the static ``surface`` (inset by ``margin`` [m]), its footprint circle at least
    ``gap`` [m] from every other object's among the first ``count`` slots (where the events before this one put
    them); the last of ``tries`` draws when none is clear. Distractor objects (``tasks.common.distractors``)."""
    margin, gap = float(margin), float(gap)

    @wp.func
    def scatter_entity(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
        rng = wp.rand_init(seed, stream)
        top = wp.transform_get_translation(ctx.entity_static_pose[surface])
        under = ctx.entity_half_extents[surface]
        mine = ctx.entity_half_extents[entity]
        radius = wp.sqrt(mine[0] * mine[0] + mine[1] * mine[1])
        x = top[0]
        y = top[1]
        for _ in range(tries):
            x = wp.randf(rng, top[0] - under[0] + margin + radius, top[0] + under[0] - margin - radius)
            y = wp.randf(rng, top[1] - under[1] + margin + radius, top[1] + under[1] - margin - radius)
            clear = True
            for k in range(count):
                if k != entity and k != surface:
                    other = ctx.entity_half_extents[k]
                    p = reset_position(ctx, w, k)
                    reach = radius + wp.sqrt(other[0] * other[0] + other[1] * other[1]) + gap
                    if (x - p[0]) * (x - p[0]) + (y - p[1]) * (y - p[1]) < reach * reach:
                        clear = False
            if clear:
                break
        set_entity_pose(ctx, w, entity, wp.vec3(x, y, top[2] + under[2] + mine[2]), wp.quat_identity())

    return scatter_entity
