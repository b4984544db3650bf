"""StackCube rewards: the dense staged reward the task declares (ManiSkill StackCube-v1 style, extended to
three cubes) and the reference's weighted terms (``reference_rewards``).

Dense reward: nine stages, each worth 1/9 (``tasks.common.rewards``; the step reward is in [0, 1], 1 at
success). For cube_2 onto cube_1, then cube_3 onto cube_2: reaching (``1 - tanh(5 |TCP - cube|)`` until the
TCP is within 6 cm), grasping, placing (``1 - tanh(5 |cube - (lower cube + (0, 0, 0.05))|)`` while grasped,
done when stacked), releasing (gripper openness while stacked, done once the cube is no longer grasped); then
success (the full stack released). cube_3's stages count only while cube_2 stays stacked and released.
"""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos
from newton_lab.task_api.cfg import RewardTermCfg
from newton_lab.tasks.common.rewards import (
    Stage, action_rate, closeness, gated, gripper_openness, reach_stage, staged_rewards,
)

from ..scene import CUBE_1, CUBE_2, CUBE_3
from .terminations import STACK_DZ, _grasped, _on
from .terminations import stack_success as _stack_success


@wp.func
def stack_error(ctx: TaskContext, w: int, top: int, bottom: int) -> float:
    """|top - bottom - (0, 0, 0.05)|: distance of cube ``top`` from its stacked pose on ``bottom`` [m]."""
    return wp.length(entity_pos(ctx, w, top) - entity_pos(ctx, w, bottom) - wp.vec3(0.0, 0.0, STACK_DZ))


def _subtask_stages(top: int, bottom: int, name: str) -> list[Stage]:
    """Reach, grasp, stack ``top`` on ``bottom``, let go (stage names ``<name>_reaching`` ...)."""

    @wp.func
    def grasped(ctx: TaskContext, w: int) -> bool:
        return _grasped(ctx, w, top)

    @wp.func
    def stacked(ctx: TaskContext, w: int) -> bool:
        return _on(ctx, w, top, bottom)

    @wp.func
    def place_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(stack_error(ctx, w, top, bottom))

    @wp.func
    def released(ctx: TaskContext, w: int) -> bool:
        return _on(ctx, w, top, bottom) and not _grasped(ctx, w, top)

    return [reach_stage(top, f"{name}_reaching"), Stage(f"{name}_grasping", grasped),
            Stage(f"{name}_placing", stacked, place_shaping), Stage(f"{name}_releasing", released, gripper_openness)]


@wp.func
def cube_2_placed(ctx: TaskContext, w: int) -> bool:
    """cube_2 stacked on cube_1 and no longer grasped: the first subtask holds."""
    return _on(ctx, w, CUBE_2, CUBE_1) and not _grasped(ctx, w, CUBE_2)


def dense_rewards() -> dict[str, RewardTermCfg]:
    """The StackCube dense reward terms (weights 1/9 each, sum in [0, 1])."""
    return staged_rewards(
        *_subtask_stages(CUBE_2, CUBE_1, "cube_2"),
        *gated(cube_2_placed, _subtask_stages(CUBE_3, CUBE_2, "cube_3")),
        Stage("success", _stack_success),
    )


# ---------------------------------------------------------------- the reference's terms (not normalised)
@wp.func
def _stack_shaping(ctx: TaskContext, w: int, top: int, bottom: int) -> float:
    return 1.0 - wp.tanh(8.0 * stack_error(ctx, w, top, bottom))


@wp.func
def cube_2_on_cube_1(ctx: TaskContext, w: int) -> float:
    """1 - tanh(8 |cube_2 - cube_1 - (0, 0, 0.05)|) (d in m)."""
    return _stack_shaping(ctx, w, CUBE_2, CUBE_1)


@wp.func
def cube_3_on_cube_2(ctx: TaskContext, w: int) -> float:
    """1 - tanh(8 |cube_3 - cube_2 - (0, 0, 0.05)|) (d in m)."""
    return _stack_shaping(ctx, w, CUBE_3, CUBE_2)


@wp.func
def stack_success(ctx: TaskContext, w: int) -> float:
    """1 with the full stack released, else 0."""
    return wp.where(_stack_success(ctx, w), 1.0, 0.0)


def reference_rewards() -> dict[str, RewardTermCfg]:
    """The reference's StackCube reward (reference §3.4): stacking shaping x2 (each), full-stack bonus x20,
    action rate x-1e-4; in about [-0.01, 24]. Opt in with ``dataclasses.replace(cfg, rewards=reference_rewards())``."""
    return {
        "cube_2_on_cube_1": RewardTermCfg(func=cube_2_on_cube_1, weight=2.0),
        "cube_3_on_cube_2": RewardTermCfg(func=cube_3_on_cube_2, weight=2.0),
        "stack_success": RewardTermCfg(func=stack_success, weight=20.0),
        "action_rate": RewardTermCfg(func=action_rate, weight=-1e-4),
    }
