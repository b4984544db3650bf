"""A commanded point: a per-row goal position in the task command (``ctx.command``), with the terms that read it.

A task declares ``command_dim=POINT_COMMAND_DIM`` and one reset event that writes the point (Reach samples it
in the base frame; ``point_from_entity`` puts it at an offset from a scene object's reset position, PushCube's
goal region). Everything else reads it through ``command_point``.
"""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, entity_coord_pos, entity_pos, write_vec3

from newton_lab.task_api.cfg import ObsTermCfg
from newton_lab.task_api.terms import term_factory

from .rewards import closeness

POINT_COMMAND_DIM = 3
"""Command columns of a point: x, y, z, world frame [m]."""


@wp.func
def command_point(ctx: TaskContext, w: int) -> wp.vec3:
    """Row ``w``'s commanded point, world frame [m]."""
    return wp.vec3(ctx.command[w, 0], ctx.command[w, 1], ctx.command[w, 2])


@wp.func
def set_command_point(ctx: TaskContext, w: int, p: wp.vec3):
    """Write row ``w``'s commanded point (reset events)."""
    for i in range(POINT_COMMAND_DIM):
        ctx.command[w, i] = p[i]


@wp.func
def command_point_obs(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The commanded point (3), world frame [m]."""
    write_vec3(out, w, col, command_point(ctx, w))


COMMAND_POINT = ObsTermCfg(func=command_point_obs, size=POINT_COMMAND_DIM, privileged=True)
"""Observation term: the commanded point (3); privileged (a target's position: ``obs_mode="sensors"`` drops it)."""


@term_factory(entities=("entity",))
def point_from_entity(*, entity: int, offset: tuple[float, float, float]):
    """Reset event: the commanded point at ``entity``'s reset position + ``offset`` (world axes [m]); list it
    after the events that place ``entity``."""
    off = wp.vec3(*(float(v) for v in offset))

    @wp.func
    def point_at_entity_offset(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
        set_command_point(ctx, w, entity_coord_pos(ctx, w, entity) + off)

    return point_at_entity_offset


@wp.func
def xy_distance_to_command(ctx: TaskContext, w: int, k: int) -> float:
    """Horizontal distance of entity ``k``'s centre from the commanded point [m]."""
    d = entity_pos(ctx, w, k) - command_point(ctx, w)
    return wp.length(wp.vec2(d[0], d[1]))


@term_factory(entities=("entity",))
def entity_at_command(*, entity: int, radius: float):
    """Predicate: ``entity``'s centre within ``radius`` [m] of the commanded point in xy (a goal region)."""
    radius = float(radius)

    @wp.func
    def entity_in_goal_region(ctx: TaskContext, w: int) -> bool:
        return xy_distance_to_command(ctx, w, entity) < radius

    return entity_in_goal_region


@term_factory(entities=("entity",))
def command_shaping(*, entity: int):
    """Reward shaping: ``1 - tanh(5 d)``, d = ``entity``'s xy distance from the commanded point [m]."""

    @wp.func
    def toward_command_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(xy_distance_to_command(ctx, w, entity))

    return toward_command_shaping
