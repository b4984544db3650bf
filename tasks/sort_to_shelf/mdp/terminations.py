"""SortToShelf predicates (reference §3.7 thresholds), built per sorting object (slot and thresholds become
compile-time constants of the generated ``@wp.func``)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import (
    TaskContext, arm_near_home, base_pose2d, entity_pos, entity_up_dot, gripper_q, held_for, tcp_pos, wrap_angle,
)

from ..objects import SHELF_NAV_YAW, SortingObject
from ..scene import OBJECT_SLOT

vec5 = wp.types.vector(length=5, dtype=float)
vec7 = wp.types.vector(length=7, dtype=float)

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
PLACE_DZ_TOL = 0.02
PLACE_GRIPPER_OPEN = 0.30
RETRACT_ARM_TOL = 0.12
DROP_Z = 0.2
TIPPED_UP_DOT = 0.5
GRASP_DIST = 0.06
GRASP_GRIPPER_MIN = 0.3


def make_at_carry(obj: SortingObject):
    """Object lifted to its minimum height and the left arm in the ready posture (Pick success)."""
    k, min_z = OBJECT_SLOT[obj.name], float(obj.lift_min_z)

    @wp.func
    def at_carry(ctx: TaskContext, w: int) -> bool:
        return entity_pos(ctx, w, k)[2] >= min_z and arm_near_home(ctx, w, CARRY_ARM_TOL)

    return at_carry


def make_at_place_start(obj: SortingObject, hold_slot: int = 0):
    """Base at the place position facing the shelf, legs and arm in the place-start posture, held 20 steps."""
    gx, gy = (float(v) for v in obj.place_base_xy)
    legs = vec5(*obj.legs)
    arm = vec7(*obj.approach_arm)
    slot = int(hold_slot)

    @wp.func
    def at_place_start(ctx: TaskContext, w: int) -> bool:
        b = base_pose2d(ctx, w)
        ok = wp.length(wp.vec2(b[0] - gx, b[1] - gy)) <= PLACE_START_BASE_TOL
        ok = ok and wp.abs(wrap_angle(b[2] - SHELF_NAV_YAW)) <= PLACE_START_YAW_TOL
        base = w * ctx.coords_per_world
        for j in range(5):
            if wp.abs(ctx.joint_q[base + ctx.leg_coord + j] - legs[j]) > PLACE_START_JOINT_TOL:
                ok = False
        for j in range(7):
            if wp.abs(ctx.joint_q[base + ctx.arm_coords[j]] - arm[j]) > PLACE_START_JOINT_TOL:
                ok = False
        return held_for(ctx, w, slot, ok, PLACE_START_HOLD)

    return at_place_start


def make_placed(obj: SortingObject):
    """Object resting in its cell (upright where required), gripper open, arm back at ready (Place success)."""
    k = OBJECT_SLOT[obj.name]
    tx, ty, tz = (float(v) for v in obj.target)
    up_min = float(obj.upright_min)

    @wp.func
    def placed(ctx: TaskContext, w: int) -> bool:
        p = entity_pos(ctx, w, k)
        ok = wp.length(wp.vec2(p[0] - tx, p[1] - ty)) <= PLACE_XY_TOL and wp.abs(p[2] - tz) <= PLACE_DZ_TOL
        ok = ok and entity_up_dot(ctx, w, k) >= up_min and wp.abs(gripper_q(ctx, w)) <= PLACE_GRIPPER_OPEN
        return ok and arm_near_home(ctx, w, RETRACT_ARM_TOL)

    return placed


def make_dropped(obj: SortingObject):
    """Object on the floor [failure]."""
    k = OBJECT_SLOT[obj.name]

    @wp.func
    def object_dropped(ctx: TaskContext, w: int) -> bool:
        return entity_pos(ctx, w, k)[2] < DROP_Z

    return object_dropped


def make_tipped(obj: SortingObject):
    """Object knocked over while it should stand (objects with an upright requirement) [failure]."""
    k = OBJECT_SLOT[obj.name]

    @wp.func
    def object_tipped(ctx: TaskContext, w: int) -> bool:
        return entity_up_dot(ctx, w, k) < TIPPED_UP_DOT

    return object_tipped


def make_grasped(obj: SortingObject):
    """TCP at the object with the gripper closed on it (subtask signal)."""
    k = OBJECT_SLOT[obj.name]

    @wp.func
    def grasped(ctx: TaskContext, w: int) -> bool:
        return wp.length(entity_pos(ctx, w, k) - tcp_pos(ctx, w)) < GRASP_DIST and gripper_q(ctx, w) > GRASP_GRIPPER_MIN

    return grasped
