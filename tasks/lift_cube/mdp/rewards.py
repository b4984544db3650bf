"""LiftCube rewards (dense shaping for RL; the expert and Mimic ignore them)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos, tcp_pos
from newton_lab.tasks.common.rewards import action_rate  # noqa: F401  (listed by the env cfg)

from ..scene import CUBE, CUBE_INIT
from .terminations import LIFT_HEIGHT

CUBE_Z0 = wp.constant(CUBE_INIT[2])
REACH_SCALE = 0.1
"""Distance scale of the reaching reward [m]."""


@wp.func
def reaching(ctx: TaskContext, w: int) -> float:
    """1 - tanh(|TCP - cube| / 0.1): 1 at the cube, ~0 far away."""
    return 1.0 - wp.tanh(wp.length(entity_pos(ctx, w, CUBE) - tcp_pos(ctx, w)) / REACH_SCALE)


@wp.func
def lift_progress(ctx: TaskContext, w: int) -> float:
    """Fraction of the 10 cm lift achieved, clamped to [0, 1]."""
    return wp.clamp((entity_pos(ctx, w, CUBE)[2] - CUBE_Z0) / LIFT_HEIGHT, 0.0, 1.0)
