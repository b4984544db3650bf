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
from newton_lab.tasks.common.rewards import (
    Stage,
    action_rate,
    gated,
    gripper_openness,
    indicator,
    place_shaping,
    reach_stage,
    staged_rewards,
)
from newton_lab.tasks.common.terminations import all_of, holding, negated

from newton_lab.task_api.cfg import RewardTermCfg
from newton_lab.task_api.terms import term_factory

from .terminations import GRIPPER_CLOSED_MIN, STACK_DZ, grasped_cube, stack_success, stacked


def _subtask_stages(top: str, bottom: str) -> list[Stage]:
    """Reach, grasp, stack ``top`` on ``bottom``, let go (stage names ``<top>_reaching`` ...)."""
    on = stacked(top, bottom)
    return [
        reach_stage(top, f"{top}_reaching"),
        Stage(f"{top}_grasping", holding(entity=top, gripper_min=GRIPPER_CLOSED_MIN)),
        Stage(f"{top}_placing", on, place_shaping(entity=top, target=bottom, offset=(0.0, 0.0, STACK_DZ))),
        Stage(f"{top}_releasing", all_of(terms=(on, negated(term=grasped_cube(top)))), gripper_openness),
    ]


def dense_rewards() -> dict[str, RewardTermCfg]:
    """The StackCube dense reward terms (weights 1/9 each, sum in [0, 1])."""
    cube_2_placed = all_of(terms=(stacked("cube_2", "cube_1"), negated(term=grasped_cube("cube_2"))))
    return staged_rewards(
        *_subtask_stages("cube_2", "cube_1"),
        *gated(cube_2_placed, _subtask_stages("cube_3", "cube_2")),
        Stage("success", stack_success()),
    )


def cube_2_rewards() -> dict[str, RewardTermCfg]:
    """The first subtask's dense reward: cube_2's four stages (1/4 each)."""
    return staged_rewards(*_subtask_stages("cube_2", "cube_1"))


def cube_3_rewards() -> dict[str, RewardTermCfg]:
    """The second subtask's dense reward: cube_3's four stages and the full stack (1/5 each)."""
    return staged_rewards(*_subtask_stages("cube_3", "cube_2"), Stage("success", stack_success()))


# ---------------------------------------------------------------- the reference's terms (not normalised)
@term_factory(entities=("top", "bottom"))
def stacking_shaping(*, top: int, bottom: int):
    """``1 - tanh(8 |top - bottom - (0, 0, 0.05)|)`` (d in m): the reference's stacking term."""

    @wp.func
    def stack_shaping(ctx: TaskContext, w: int) -> float:
        d = wp.length(entity_pos(ctx, w, top) - entity_pos(ctx, w, bottom) - wp.vec3(0.0, 0.0, STACK_DZ))
        return 1.0 - wp.tanh(8.0 * d)

    return stack_shaping


def reference_rewards() -> dict[str, RewardTermCfg]:
    """The reference platform's StackCube reward: stacking shaping x2 (each), full-stack bonus x20,
    action rate x-1e-4; in about [-0.01, 24]. Opt in with ``dataclasses.replace(cfg, rewards=reference_rewards())``."""
    return {
        "cube_2_on_cube_1": RewardTermCfg(
            func=stacking_shaping, params={"top": "cube_2", "bottom": "cube_1"}, weight=2.0
        ),
        "cube_3_on_cube_2": RewardTermCfg(
            func=stacking_shaping, params={"top": "cube_3", "bottom": "cube_2"}, weight=2.0
        ),
        "stack_success": RewardTermCfg(func=indicator(term=stack_success()), weight=20.0),
        "action_rate": RewardTermCfg(func=action_rate, weight=-1e-4),
    }
