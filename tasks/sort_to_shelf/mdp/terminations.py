"""SortToShelf predicates (the reference platform's thresholds) for one sorting object: the generic terms
(``tasks.common.terminations``) with the object's name, heights and cell."""

from __future__ import annotations

from newton_lab.tasks.common.terminations import (
    all_of,
    arm_at_home,
    at_point,
    at_posture,
    base_at,
    grasped,
    gripper_open,
    held,
    lifted,
    upright,
)

from ..objects import SHELF_NAV_YAW, SortingObject

CARRY_ARM_TOL = 0.16
"""Pick success: every left-arm joint within this of the ready posture [rad]."""
PLACE_START_BASE_TOL = 0.05
"""Nav success: base within this of the place base position [m] ..."""
PLACE_START_YAW_TOL = 0.10
"""... facing the shelf within this [rad] ..."""
PLACE_START_JOINT_TOL = 0.12
"""... legs and arm within this of the place-start posture [rad] ..."""
PLACE_START_HOLD = 20
"""... for this many consecutive steps."""
PLACE_XY_TOL = 0.10
"""Place: object centre within this xy distance of its cell target [m] ..."""
PLACE_DZ_TOL = 0.02
"""... and this height difference [m] ..."""
PLACE_GRIPPER_OPEN = 0.30
"""... the gripper open within this [rad] ..."""
RETRACT_ARM_TOL = 0.12
"""... and the arm back at ready within this [rad]."""
DROP_Z = 0.2
"""An object centre below this is on the floor [m]."""


def grasped_object(obj: SortingObject):
    """TCP at the object with the gripper closed on it (subtask signal)."""
    return grasped(entity=obj.name)


def at_carry(obj: SortingObject):
    """Object lifted to its minimum height and the left arm in the ready posture (stateless)."""
    return all_of(terms=(lifted(entity=obj.name, min_z=obj.lift_min_z), arm_at_home(tol=CARRY_ARM_TOL)))


CARRY_HOLD = 10
"""Pick success holds this many consecutive steps: a demo then shows the arm settling inside the ready band (a
success on the step the arm entered it left policies hovering just outside)."""


def held_at_carry(obj: SortingObject):
    """``at_carry`` held ``CARRY_HOLD`` steps (Pick success)."""
    return held(term=at_carry(obj), steps=CARRY_HOLD)


def at_place_start(obj: SortingObject):
    """Base at the place position facing the shelf, legs and arm in the place-start posture (stateless)."""
    return all_of(
        terms=(
            base_at(
                goal_xy=obj.place_base_xy,
                radius=PLACE_START_BASE_TOL,
                goal_yaw=SHELF_NAV_YAW,
                yaw_tol=PLACE_START_YAW_TOL,
            ),
            at_posture(arm=obj.approach_arm, legs=obj.legs, tol=PLACE_START_JOINT_TOL),
        )
    )


def held_at_place_start(obj: SortingObject):
    """``at_place_start`` held 20 steps (Nav success)."""
    return held(term=at_place_start(obj), steps=PLACE_START_HOLD)


def in_cell(obj: SortingObject):
    """Object resting in its cell (upright where required), whatever the gripper does."""
    return all_of(
        terms=(
            at_point(entity=obj.name, point=obj.target, xy_tol=PLACE_XY_TOL, z_tol=PLACE_DZ_TOL),
            upright(entity=obj.name, min_up_dot=obj.upright_min),
        )
    )


def released_in_cell(obj: SortingObject):
    """Object in its cell with the gripper open."""
    return all_of(terms=(in_cell(obj), gripper_open(tol=PLACE_GRIPPER_OPEN)))


def placed(obj: SortingObject):
    """Object in its cell, gripper open, arm back at ready (Place success)."""
    return all_of(terms=(released_in_cell(obj), arm_at_home(tol=RETRACT_ARM_TOL)))
