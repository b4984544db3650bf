"""SortToShelf-All's own expert: the Return component's (legs down, arm at ready, then drive back to the table).
The other phases run SortToShelf's component experts for the row's target object."""

from __future__ import annotations

from newton_lab.tasks.common.config.g1 import postures
from newton_lab.tasks.sort_to_shelf.config.g1.env_cfg import NAV_SUCCESS_RADIUS

from newton_lab.robots.g1 import spec
from newton_lab.task_api.experts import JointTargetExpert, NavExpert, SequenceExpert

from .env_cfg import TABLE_LEGS, TABLE_XY


def return_expert(sorting_object: str | None = None, init_scenario: str | None = None) -> SequenceExpert:
    """Arm to ready and legs down (ramped), then turn to face the table and drive straight to the reset position."""
    return SequenceExpert(
        steps=(
            (
                "posture_arm",
                JointTargetExpert(
                    targets=dict(zip(spec.LEFT_ARM_JOINTS, postures.CARRY_LEFT_ARM)), max_step=0.04, tolerance=0.12
                ),
            ),
            (
                "posture_legs",
                JointTargetExpert(targets=dict(zip(spec.LEG_JOINTS, TABLE_LEGS)), max_step=0.04, tolerance=0.05),
            ),
            (
                "drive",
                NavExpert(
                    goal=TABLE_XY,
                    goal_yaw=0.0,
                    success_radius=NAV_SUCCESS_RADIUS,
                    yaw_tolerance=0.04,
                    rotate_before_translate=True,
                    waypoint_spacing=10.0,
                ),
            ),
        )
    )
