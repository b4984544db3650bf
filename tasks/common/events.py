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
