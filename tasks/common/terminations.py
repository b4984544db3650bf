"""Predicates every task can list (success, failure, subtask signals, reward stages), parametrised by name.

Each is a ``@term_factory``: ``grasped(entity="cube")`` is a bound term; the env resolves ``"cube"`` to its
slot and bakes slot and thresholds into the generated ``@wp.func (ctx, w) -> bool``. Thresholds default to
the reference platform's table-top values; a task passes its own where they differ.
"""

from __future__ import annotations

from typing import Any

import warp as wp
from newton_lab.kernels.context import (
    TaskContext,
    arm_near_home,
    base_pose2d,
    entity_pos,
    entity_up_dot,
    finger_lag,
    finger_middle,
    gripper_q,
    held_for,
    in_tcp_frame,
    tcp_distance,
    wrap_angle,
)

from newton_lab.task_api.terms import term_factory

GRASP_DIST = 0.06
"""TCP within this distance of the object's centre for a grasp [m]."""
GRASP_GRIPPER_MIN = 0.3
"""Gripper closed on the object: the authored fingers stop on a 5 cm object near 0.67 rad, so 0.3 separates
open from closed-on-object [rad]. (The reference's 1.2 equals the closed target and never fires on an object.)"""
HOLD_FINGER_LAG = 0.005
"""An object is between the fingers when each stopped at least this far short of the master's drive [m] (the G1
closed on a 5 cm cube: 1.6 cm; closed on nothing: under 1 mm)."""
HOLD_CENTRE_TOL = 0.006
"""A held object's centre lies within this of the middle between the fingers, along their closing axis [m]: what
the fingers squeeze sits between them (the G1 experts' grasps in LiftCube, PickCube, StackCube, PickToShelf and
SortToShelf: under 0.6 mm from the TCP's axis; PPO's grasps of the cube in LiftCube and PickCube, fingers unevenly
closed: 99 % within 3.6 mm of their middle; PPO's fingers stopped on a LiftCube cube's corner: 95 % beyond 8.9 mm,
median 15 mm)."""
GRIPPER_OPEN_TOL = 0.05
"""Gripper counts as open at or below this [rad]."""


@term_factory(entities=("entity",))
def grasped(*, entity: int, max_dist: float = GRASP_DIST, gripper_min: float = GRASP_GRIPPER_MIN):
    """TCP within ``max_dist`` [m] of ``entity``'s centre with the gripper closed past ``gripper_min`` [rad]."""
    max_dist, gripper_min = float(max_dist), float(gripper_min)

    @wp.func
    def grasped_entity(ctx: TaskContext, w: int) -> bool:
        return tcp_distance(ctx, w, entity) < max_dist and wp.abs(gripper_q(ctx, w)) > gripper_min

    return grasped_entity


@term_factory()
def fingers_blocked(*, min_lag: float = HOLD_FINGER_LAG):
    """Something is between the fingers: each stopped at least ``min_lag`` [m] short of where the gripper master
    drives it (``finger_lag``)."""
    min_lag = float(min_lag)

    @wp.func
    def fingers_stopped(ctx: TaskContext, w: int) -> bool:
        return finger_lag(ctx, w) > min_lag

    return fingers_stopped


@term_factory(entities=("entity",))
def between_fingers(*, entity: int, max_offset: float = HOLD_CENTRE_TOL):
    """``entity``'s centre between the finger pads: within ``max_offset`` [m] of their middle along the closing axis
    (TCP y, ``finger_middle``) and short of the fingertips (``RobotBinding.fingertip_reach``, along TCP x). Along
    the third axis a side grasp of a tall object sits off its centre (PickToShelf's expert: up to 3 cm)."""
    max_offset = float(max_offset)

    @wp.func
    def entity_between_fingers(ctx: TaskContext, w: int) -> bool:
        p = in_tcp_frame(ctx, w, entity)
        return wp.abs(p[1] - finger_middle(ctx, w)) < max_offset and p[0] < ctx.fingertip_reach

    return entity_between_fingers


def holding(*, entity: str, **grasp):
    """``grasped(entity=entity, **grasp)`` with the fingers blocked (``fingers_blocked``) by the object
    (``between_fingers``): the grasp of the reward stages. ``grasped`` alone also holds for a gripper closed on
    nothing beside the object (its TCP 4.5 cm from the cube's centre), and ``grasped`` with blocked fingers for
    fingers stopped on a cube's corner or pressed into the table beside it: states worth as much as a real grasp to
    PPO, which it found and stayed at (LiftCube, 4096 envs on an H200)."""
    return all_of(terms=(grasped(entity=entity, **grasp), fingers_blocked(), between_fingers(entity=entity)))


@term_factory(entities=("entity",))
def lifted(*, entity: int, min_z: float):
    """``entity``'s centre at or above height ``min_z`` [m] (world z)."""
    min_z = float(min_z)

    @wp.func
    def entity_lifted(ctx: TaskContext, w: int) -> bool:
        return entity_pos(ctx, w, entity)[2] >= min_z

    return entity_lifted


@term_factory(entities=("entity",))
def dropped(*, entity: int, below_z: float):
    """``entity``'s centre below height ``below_z`` [m]: it fell off the table or out of the hand [failure]."""
    below_z = float(below_z)

    @wp.func
    def entity_dropped(ctx: TaskContext, w: int) -> bool:
        return entity_pos(ctx, w, entity)[2] < below_z

    return entity_dropped


@term_factory(entities=("entity",))
def upright(*, entity: int, min_up_dot: float):
    """|``entity``'s local z . world z| at least ``min_up_dot`` (1 = upright; 0 checks nothing)."""
    min_up_dot = float(min_up_dot)

    @wp.func
    def entity_upright(ctx: TaskContext, w: int) -> bool:
        return entity_up_dot(ctx, w, entity) >= min_up_dot

    return entity_upright


@term_factory(entities=("entity",))
def tipped(*, entity: int, max_up_dot: float = 0.5):
    """``entity``'s axis more than acos(``max_up_dot``) from vertical (0.5: 60 deg): knocked over [failure]."""
    max_up_dot = float(max_up_dot)

    @wp.func
    def entity_tipped(ctx: TaskContext, w: int) -> bool:
        return entity_up_dot(ctx, w, entity) < max_up_dot

    return entity_tipped


@term_factory(entities=("entity", "target"))
def resting_on(*, entity: int, target: int, height: float, xy_tol: float, z_tol: float):
    """``entity``'s centre within ``xy_tol`` [m] of ``target``'s in xy and ``height`` +- ``z_tol`` [m] above it:
    resting on it (a cube on a block, a stacked cube, a bar on a deck)."""
    height, xy_tol, z_tol = float(height), float(xy_tol), float(z_tol)

    @wp.func
    def entity_resting_on(ctx: TaskContext, w: int) -> bool:
        a = entity_pos(ctx, w, entity)
        b = entity_pos(ctx, w, target)
        dxy = wp.length(wp.vec2(a[0] - b[0], a[1] - b[1]))
        return dxy < xy_tol and wp.abs(a[2] - b[2] - height) < z_tol

    return entity_resting_on


@term_factory(entities=("entity",))
def at_point(*, entity: int, point: tuple[float, float, float], xy_tol: float, z_tol: float = 1.0e9):
    """``entity``'s centre within ``xy_tol`` [m] of ``point`` in xy and ``z_tol`` [m] in z (world frame)."""
    xy_tol, z_tol = float(xy_tol), float(z_tol)
    px, py, pz = (float(v) for v in point)

    @wp.func
    def entity_at_point(ctx: TaskContext, w: int) -> bool:
        p = entity_pos(ctx, w, entity)
        return wp.length(wp.vec2(p[0] - px, p[1] - py)) <= xy_tol and wp.abs(p[2] - pz) <= z_tol

    return entity_at_point


@term_factory()
def gripper_open(*, tol: float = GRIPPER_OPEN_TOL):
    """Gripper master joint within ``tol`` [rad] of open (0)."""
    tol = float(tol)

    @wp.func
    def gripper_is_open(ctx: TaskContext, w: int) -> bool:
        return wp.abs(gripper_q(ctx, w)) <= tol

    return gripper_is_open


@term_factory()
def arm_at_home(*, tol: float):
    """Every joint of the controlled arm within ``tol`` [rad] of the task's ``arm_home`` posture."""
    tol = float(tol)

    @wp.func
    def arm_home(ctx: TaskContext, w: int) -> bool:
        return arm_near_home(ctx, w, tol)

    return arm_home


@wp.func
def posture_error(ctx: TaskContext, w: int, legs: Any, arm: Any, check_legs: bool) -> wp.vec2:
    """(Euclidean distance [rad], largest joint error [rad]) of the lift joints (``ctx.lift_coords``, when
    ``check_legs``) and the controlled arm (``ctx.arm_coords``) from ``legs`` / ``arm`` (float vectors, one value
    per joint; ``posture_vectors``)."""
    base = w * ctx.coords_per_world
    s = float(0.0)
    m = float(0.0)
    if check_legs:
        for j in range(wp.min(len(legs), ctx.lift_coords.shape[0])):
            d = ctx.joint_q[base + ctx.lift_coords[j]] - legs[j]
            s += d * d
            m = wp.max(m, wp.abs(d))
    for j in range(wp.min(len(arm), ctx.arm_coords.shape[0])):
        d = ctx.joint_q[base + ctx.arm_coords[j]] - arm[j]
        s += d * d
        m = wp.max(m, wp.abs(d))
    return wp.vec2(wp.sqrt(s), m)


def posture_vectors(arm: tuple[float, ...], legs: tuple[float, ...] | None):
    """``(arm, legs, check_legs)`` of a posture (one value per arm / lift joint of the robot, in its binding's
    order), as ``posture_error`` takes them (legs unchecked when ``None``) [rad]."""
    if not arm:
        raise ValueError("a posture needs one arm joint value per joint of the controlled arm; got none")
    arm_q = wp.types.vector(length=len(arm), dtype=float)(*(float(v) for v in arm))
    legs = tuple(legs) if legs else None
    legs_q = wp.types.vector(length=len(legs or (0.0,)), dtype=float)(*(float(v) for v in (legs or (0.0,))))
    return arm_q, legs_q, legs is not None


@term_factory()
def at_posture(*, arm: tuple[float, ...], tol: float, legs: tuple[float, ...] | None = None):
    """Every joint of the controlled arm and, when ``legs`` is given, every lift joint (``RobotBinding.leg_joints``)
    within ``tol`` [rad] of that posture."""
    tol = float(tol)
    arm_q, legs_q, check_legs = posture_vectors(arm, legs)

    @wp.func
    def joints_at_posture(ctx: TaskContext, w: int) -> bool:
        return posture_error(ctx, w, legs_q, arm_q, check_legs)[1] <= tol

    return joints_at_posture


@term_factory()
def base_at(*, goal_xy: tuple[float, float], radius: float, goal_yaw: float = 0.0, yaw_tol: float = 10.0):
    """Planar base within ``radius`` [m] of ``goal_xy`` and, when ``yaw_tol`` < pi, within ``yaw_tol`` [rad] of
    ``goal_yaw`` (env frame)."""
    radius, goal_yaw, yaw_tol = float(radius), float(goal_yaw), float(yaw_tol)
    gx, gy = (float(v) for v in goal_xy)

    @wp.func
    def base_at_goal(ctx: TaskContext, w: int) -> bool:
        b = base_pose2d(ctx, w)
        return wp.length(wp.vec2(b[0] - gx, b[1] - gy)) <= radius and wp.abs(wrap_angle(b[2] - goal_yaw)) <= yaw_tol

    return base_at_goal


@term_factory()
def all_of(*, terms: tuple):
    """Every predicate of ``terms`` holds (evaluated in order, all of them)."""
    n = len(terms)

    @wp.func
    def all_hold(ctx: TaskContext, w: int) -> bool:
        ok = bool(True)
        for k in range(wp.static(n)):
            if not wp.static(terms[k])(ctx, w):
                ok = False
        return ok

    return all_hold


@term_factory()
def any_of(*, terms: tuple):
    """At least one predicate of ``terms`` holds (all of them evaluated)."""
    n = len(terms)

    @wp.func
    def any_holds(ctx: TaskContext, w: int) -> bool:
        ok = bool(False)
        for k in range(wp.static(n)):
            if wp.static(terms[k])(ctx, w):
                ok = True
        return ok

    return any_holds


@term_factory()
def negated(*, term):
    """``term`` does not hold."""

    @wp.func
    def does_not_hold(ctx: TaskContext, w: int) -> bool:
        return not term(ctx, w)

    return does_not_hold


@term_factory(hold_counter=True)
def held(*, term, steps: int, hold_slot: int = 0):
    """``term`` has held for ``steps`` consecutive control steps (a counter of its own, restarted with each
    phase). Stateful: list it as a phase's success, never as a reward stage or a signal."""
    steps = int(steps)

    @wp.func
    def held_long_enough(ctx: TaskContext, w: int) -> bool:
        return held_for(ctx, w, hold_slot, term(ctx, w), steps)

    return held_long_enough
