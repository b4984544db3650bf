"""SortToShelf dense rewards, built per sorting object (ManiSkill PickCube-v1 style, ``tasks.common.rewards``;
each in [0, 1], 1 when the task's success condition holds).

Pick: reaching (``1 - tanh(5 |TCP - object|)`` until within 6 cm), grasping, lifting (``1 - tanh(5 dz)``
while grasped, dz = height still to go to the object's lift height [m]), carrying (``1 - tanh(|q_arm -
ready|)``, rad): 1/4 each. Place: grasping (object in hand), placing (``1 - tanh(5 |object - cell target|)``
while grasped, done when it rests in its cell, upright where required), releasing (gripper openness, done
with the gripper open), retracting (``1 - tanh(|q_arm - ready|)``, done at success): 1/4 each.
Coherent task: ``(phase + r_phase) / 3`` with the pick, nav (driving: mean of ``1 - tanh(d)`` to the place
base position, d in m, and ``1 - tanh(|yaw error|)``; posing: ``1 - tanh(|q_legs,arm - place start|)``, rad)
and place rewards.
"""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, base_pose2d, entity_pos, entity_up_dot, gripper_q, wrap_angle
from newton_lab.task_api.cfg import RewardTermCfg
from newton_lab.tasks.common.rewards import (
    Stage, arm_home_error, closeness, drive_stage, gripper_openness, phased_rewards, pick_to_carry_stages,
    posture_closeness, staged_rewards,
)

from ..objects import SHELF_NAV_YAW, SortingObject
from ..scene import OBJECT_SLOT
from .terminations import (
    PLACE_DZ_TOL, PLACE_GRIPPER_OPEN, PLACE_START_BASE_TOL, PLACE_START_JOINT_TOL, PLACE_START_YAW_TOL,
    PLACE_XY_TOL, make_at_carry, make_grasped, make_placed,
)

vec5 = wp.types.vector(length=5, dtype=float)
vec7 = wp.types.vector(length=7, dtype=float)


def pick_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """SortToShelf-Pick: reach, grasp, lift, ready posture (1/4 each)."""
    return staged_rewards(*pick_to_carry_stages(obj=OBJECT_SLOT[obj.name], grasped=make_grasped(obj),
                                                lift_z=obj.lift_min_z, at_carry=make_at_carry(obj)))


def place_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """SortToShelf-Place: hold, place in the cell, release, retract (1/4 each)."""
    k = OBJECT_SLOT[obj.name]
    target = wp.vec3(*(float(v) for v in obj.target))
    up_min = float(obj.upright_min)

    @wp.func
    def in_cell(ctx: TaskContext, w: int) -> bool:
        p = entity_pos(ctx, w, k)
        ok = wp.length(wp.vec2(p[0] - target[0], p[1] - target[1])) <= PLACE_XY_TOL
        return ok and wp.abs(p[2] - target[2]) <= PLACE_DZ_TOL and entity_up_dot(ctx, w, k) >= up_min

    @wp.func
    def place_shaping(ctx: TaskContext, w: int) -> float:
        return closeness(wp.length(entity_pos(ctx, w, k) - target))

    @wp.func
    def released(ctx: TaskContext, w: int) -> bool:
        return in_cell(ctx, w) and wp.abs(gripper_q(ctx, w)) <= PLACE_GRIPPER_OPEN

    @wp.func
    def retract_shaping(ctx: TaskContext, w: int) -> float:
        return posture_closeness(arm_home_error(ctx, w))

    return staged_rewards(Stage("grasping", make_grasped(obj)), Stage("placing", in_cell, place_shaping),
                          Stage("releasing", released, gripper_openness),
                          Stage("retracting", make_placed(obj), retract_shaping))


def _posing_stage(obj: SortingObject) -> Stage:
    """Legs and left arm at the place-start posture with the base in place (the Nav success condition without
    its 20-step hold); shaping ``1 - tanh(|q_legs,arm - place start|)`` [rad]."""
    gx, gy = (float(v) for v in obj.place_base_xy)
    legs, arm = vec5(*obj.legs), vec7(*obj.approach_arm)

    @wp.func
    def posture_error(ctx: TaskContext, w: int) -> float:
        base = w * ctx.coords_per_world
        s = float(0.0)
        for j in range(5):
            d = ctx.joint_q[base + ctx.leg_coord + j] - legs[j]
            s += d * d
        for j in range(7):
            d = ctx.joint_q[base + ctx.arm_coords[j]] - arm[j]
            s += d * d
        return wp.sqrt(s)

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
        return ok

    @wp.func
    def posing_shaping(ctx: TaskContext, w: int) -> float:
        return posture_closeness(posture_error(ctx, w))

    return Stage("posing", at_place_start, posing_shaping)


def nav_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """The nav phase of the coherent task: drive to the place base position facing the shelf, then the place-start
    posture (1/2 each)."""
    drive = drive_stage(goal_xy=obj.place_base_xy, goal_yaw=SHELF_NAV_YAW, radius=PLACE_START_BASE_TOL,
                        yaw_tol=PLACE_START_YAW_TOL)
    return staged_rewards(drive, _posing_stage(obj))


def coherent_rewards(obj: SortingObject) -> dict[str, RewardTermCfg]:
    """SortToShelf-v0: ``(phase + r_phase) / 3`` over pick, nav, place."""
    return phased_rewards([("pick", pick_rewards(obj)), ("nav", nav_rewards(obj)), ("place", place_rewards(obj))])
