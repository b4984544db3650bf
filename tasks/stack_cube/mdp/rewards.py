"""StackCube rewards (reference weights are set in the env cfg)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos
from newton_lab.tasks.common.rewards import action_rate  # noqa: F401  (listed by the env cfg)

from ..scene import CUBE_1, CUBE_2, CUBE_3
from .terminations import stack_success as _stack_success


@wp.func
def _stack_shaping(ctx: TaskContext, w: int, top: int, bottom: int) -> float:
    d = entity_pos(ctx, w, top) - entity_pos(ctx, w, bottom) - wp.vec3(0.0, 0.0, 0.05)
    return 1.0 - wp.tanh(8.0 * wp.length(d))


@wp.func
def cube_2_on_cube_1(ctx: TaskContext, w: int) -> float:
    """1 - tanh(8 |cube_2 - cube_1 - (0, 0, 0.05)|)."""
    return _stack_shaping(ctx, w, CUBE_2, CUBE_1)


@wp.func
def cube_3_on_cube_2(ctx: TaskContext, w: int) -> float:
    return _stack_shaping(ctx, w, CUBE_3, CUBE_2)


@wp.func
def stack_success(ctx: TaskContext, w: int) -> float:
    return wp.where(_stack_success(ctx, w), 1.0, 0.0)
