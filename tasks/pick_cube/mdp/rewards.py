"""PickCube dense reward (ManiSkill PickCube-v1 style; the expert and Mimic ignore it).

Five stages, each worth 0.2 (``tasks.common.rewards``; the step reward is in [0, 1], 1 at success):
reaching (``1 - tanh(5 |TCP - cube|)`` until the TCP is within 6 cm), grasping (cube in the closed gripper),
placing (``1 - tanh(5 |cube - goal|)`` while grasped, goal = cube resting on the blue block), releasing
(gripper openness while the cube rests on the block), success (released on the block).
"""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos
from newton_lab.tasks.common.rewards import Stage, closeness, gripper_openness, reach_stage, staged_rewards

from ..scene import BLUE_BLOCK, CUBE
from .terminations import RELEASE_DZ, RELEASE_DZ_TOL, RELEASE_XY_TOL, grasped_cube, released_on_blue_block


@wp.func
def goal_distance(ctx: TaskContext, w: int) -> float:
    """|cube - (block centre + (0, 0, 0.035))|: distance to the cube's resting pose on the block [m]."""
    return wp.length(entity_pos(ctx, w, CUBE) - entity_pos(ctx, w, BLUE_BLOCK) - wp.vec3(0.0, 0.0, RELEASE_DZ))


@wp.func
def cube_on_block(ctx: TaskContext, w: int) -> bool:
    """Cube within the success tolerances of its resting pose on the block, whatever the gripper does."""
    c = entity_pos(ctx, w, CUBE)
    b = entity_pos(ctx, w, BLUE_BLOCK)
    dxy = wp.length(wp.vec2(c[0] - b[0], c[1] - b[1]))
    return dxy < RELEASE_XY_TOL and wp.abs(c[2] - b[2] - RELEASE_DZ) < RELEASE_DZ_TOL


@wp.func
def place_shaping(ctx: TaskContext, w: int) -> float:
    """``1 - tanh(5 goal_distance)`` [m -> 0..1] (counted while grasped)."""
    return closeness(goal_distance(ctx, w))


def dense_rewards():
    """The PickCube reward terms (weights 0.2 each, sum in [0, 1])."""
    return staged_rewards(
        reach_stage(CUBE),
        Stage("grasping", grasped_cube),
        Stage("placing", cube_on_block, place_shaping),
        Stage("releasing", released_on_blue_block, gripper_openness),
        Stage("success", released_on_blue_block),
    )
