"""LiftCube expert plan: top-down approach, grasp, straight lift 14 cm (TCP targets resolved at reset)."""

from __future__ import annotations

from newton_lab.task_api.motion_plan import AssetTarget, MotionPlan, MotionStep


def plan() -> MotionPlan:
    return MotionPlan(
        steps=(
            MotionStep(name="approach_cube", target=AssetTarget("cube", (0.0, 0.0, 0.205))),
            MotionStep(name="descend_to_cube", target=AssetTarget("cube", (0.0, 0.0, 0.035))),
            MotionStep(name="close_left_gripper", gripper_open=False, hold=25),
            MotionStep(
                name="lift_cube", target=AssetTarget("cube", (0.0, 0.0, 0.175)), gripper_open=False, linear=4, hold=20
            ),
        ),
        max_joint_step=0.03,
        settle_steps=12,
    )
