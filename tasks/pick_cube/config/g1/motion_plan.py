"""PickCube expert plan (the reference platform's, but for the release): all TCP targets top-down, resolved at reset.

The reference holds the cube still above the block for 12 frames before it opens the gripper; here the last 2 cm are
lowered at 0.004 rad a step and the gripper opens on arrival. On the 2-core CPU (100 expert demos, the demo
pipeline's training config at 6,000 steps, 80 held-out randomised episodes) a state policy placed **54 of 80**
against 38 with the still frames, where it stalled; the expert places 100 of 100 either way (benchmarks history)."""

from __future__ import annotations

import numpy as np

from newton_lab.task_api.motion_plan import AssetTarget, MotionPlan, MotionStep


def _above_block(poses: dict[str, np.ndarray]) -> np.ndarray:
    """Block xy at max(cube z + 0.135, block z + 0.12): high enough to carry the cube over."""
    block, cube = poses["blue_block"], poses["cube"]
    z = np.maximum(cube[:, 2] + 0.135, block[:, 2] + 0.07 + 0.05)
    return np.stack([block[:, 0], block[:, 1], z], axis=1)


def plan() -> MotionPlan:
    return MotionPlan(
        steps=(
            MotionStep(name="approach_cube", target=AssetTarget("cube", (0.0, 0.0, 0.205))),
            MotionStep(name="descend_to_cube", target=AssetTarget("cube", (0.0, 0.0, 0.035))),
            MotionStep(name="close_left_gripper", gripper_open=False, hold=25),
            MotionStep(name="lift_cube", target=AssetTarget("cube", (0.0, 0.0, 0.135)), gripper_open=False),
            MotionStep(name="move_above_target", target=_above_block, gripper_open=False),
            MotionStep(
                name="descend_to_target", target=AssetTarget("blue_block", (0.0, 0.0, 0.09)), gripper_open=False
            ),
            MotionStep(
                name="lower_onto_target",
                target=AssetTarget("blue_block", (0.0, 0.0, 0.07)),
                gripper_open=False,
                max_joint_step=0.004,
                settle=False,
            ),
            MotionStep(name="open_left_gripper", target=AssetTarget("blue_block", (0.0, 0.0, 0.07))),
        ),
        max_joint_step=0.03,
        settle_steps=12,
    )
