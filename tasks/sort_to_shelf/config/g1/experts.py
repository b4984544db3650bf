"""SortToShelf experts (reference plans): side grasp and lift, drive -> legs -> arm, place in the cell."""

from __future__ import annotations

from newton_lab.tasks.common.config.g1 import postures
from newton_lab.tasks.sort_to_shelf.objects import SHELF_NAV_YAW, sorting_object as lookup_object

from newton_lab.robots.g1 import spec
from newton_lab.task_api.experts import JointTargetExpert, NavExpert, SequenceExpert
from newton_lab.task_api.motion_plan import AssetTarget, MotionPlan, MotionStep, WorldTarget

from .env_cfg import NAV_SUCCESS_RADIUS


def _place_quat():
    return (0.70710678, -0.70710678, 0.0, 0.0)


def pick_plan(sorting_object: str | None = None) -> MotionPlan:
    """Side grasp of the object, lift, ready posture (reference SortToShelf-Pick plan, settle 6)."""
    o = lookup_object(sorting_object).name
    side = postures.SIDE_GRASP_TCP_QUAT
    return MotionPlan(
        steps=(
            MotionStep(name=f"pre_approach_{o}", target=AssetTarget(o, (-0.20, 0.0, 0.14)), quat=side, linear=6),
            MotionStep(name=f"approach_{o}", target=AssetTarget(o, (-0.12, 0.0, 0.025)), quat=side, linear=4),
            MotionStep(name=f"descend_to_{o}", target=AssetTarget(o, (-0.01, 0.0, 0.025)), quat=side, linear=4),
            MotionStep(name="close_left_gripper", gripper_open=False, hold=25),
            MotionStep(
                name=f"lift_{o}", target=AssetTarget(o, (0.0, 0.0, 0.22)), quat=side, gripper_open=False, linear=3
            ),
            MotionStep(name=f"carry_{o}", joints=postures.CARRY_LEFT_ARM, gripper_open=False, hold=10),
        ),
        max_joint_step=0.04,
        settle_steps=6,
    )


def place_plan(sorting_object: str | None = None, init_scenario: str | None = None) -> MotionPlan:
    """Into the cell facing the shelf, down to the release height, let go, back out, arm to ready."""
    obj = lookup_object(sorting_object)
    x, y, z = obj.release_tcp
    approach = WorldTarget((x, y + 0.24, z + 0.07))
    insert = WorldTarget((x, y, z + 0.07))
    release = WorldTarget((x, y, z))
    q, cell = _place_quat(), obj.cell
    return MotionPlan(
        steps=(
            MotionStep(name=f"approach_{cell}", target=approach, quat=q, gripper_open=False),
            MotionStep(name=f"insert_to_{cell}", target=insert, quat=q, gripper_open=False, linear=4),
            MotionStep(name=f"descend_to_{cell}", target=release, quat=q, gripper_open=False, linear=2),
            MotionStep(name=f"release_on_{cell}", target=release, quat=q, hold=35),
            MotionStep(name=f"retreat_from_{cell}", target=approach, quat=q, hold=20, linear=4),
            MotionStep(name=f"retract_left_arm_from_{cell}", joints=postures.CARRY_LEFT_ARM, hold=20),
        ),
        max_joint_step=0.04,
        settle_steps=6,
    )


def nav_expert(sorting_object: str | None = None) -> NavExpert:
    """Drive only: turn to face the shelf, then straight to the object's place position."""
    obj = lookup_object(sorting_object)
    return NavExpert(
        goal=obj.place_base_xy,
        goal_yaw=SHELF_NAV_YAW,
        success_radius=NAV_SUCCESS_RADIUS,
        yaw_tolerance=0.04,
        rotate_before_translate=True,
        waypoint_spacing=10.0,
    )


def nav_sequence_expert(sorting_object: str | None = None, init_scenario: str | None = None) -> SequenceExpert:
    """The Nav expert: drive -> legs (ramped, lifted for the upper row) -> arm to the place-start posture."""
    obj = lookup_object(sorting_object)
    return SequenceExpert(
        steps=(
            ("drive", nav_expert(obj.name)),
            (
                "posture_legs",
                JointTargetExpert(
                    targets=dict(zip(spec.LEG_JOINTS, obj.legs)), max_step=0.04, tolerance=0.12, hold_steps=20
                ),
            ),
            (
                "posture_arm",
                JointTargetExpert(
                    targets=dict(zip(spec.LEFT_ARM_JOINTS, obj.approach_arm)), max_step=0.04, tolerance=0.12
                ),
            ),
        )
    )
