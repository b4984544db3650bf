"""PickCube expert plan (as on the reference platform): all TCP targets top-down, resolved at reset."""

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
            MotionStep(name="descend_to_target", target=AssetTarget("blue_block", (0.0, 0.0, 0.07)), gripper_open=False),
            MotionStep(name="open_left_gripper", target=AssetTarget("blue_block", (0.0, 0.0, 0.07))),
        ),
        max_joint_step=0.03,
        settle_steps=12,
    )
