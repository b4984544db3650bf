"""PickToShelf predicates (reference §3.6 thresholds)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import (
    TaskContext, arm_near_home, entity_pos, entity_up_dot, gripper_q, held_for, tcp_pos,
)

from ..scene import CUBE, DECK

CARRY_MIN_Z = 0.465
"""Bar centre at or above table top 0.325 + half height 0.08 + lift 0.06 [m]."""
CARRY_ARM_TOL = 0.12
"""Every left-arm joint within this of the carry posture [rad]."""
SHELF_XY_TOL = 0.10
"""Bar centre within this xy distance of the deck centre [m]."""
SHELF_DZ = 0.095
"""Expected bar-above-deck-centre height: deck half 0.015 + bar half 0.08 [m]."""
SHELF_DZ_TOL = 0.04
UPRIGHT_MIN = 0.90
GRIPPER_OPEN_TOL = 0.05
PLACE_HOLD_STEPS = 20
DROP_Z = 0.2
"""A bar whose centre is this low has fallen off the table / out of the hand [m]."""
TIPPED_UP_DOT = 0.5
GRASP_DIST = 0.06
GRASP_GRIPPER_MIN = 0.3
"""Gripper closed on the bar (the fingers stop on a 5 cm bar near 0.67 rad)."""



@wp.func
def at_carry(ctx: TaskContext, w: int) -> bool:
    """Bar lifted off the table and the left arm in the carry posture (Pick success)."""
    return entity_pos(ctx, w, CUBE)[2] >= CARRY_MIN_Z and arm_near_home(ctx, w, CARRY_ARM_TOL)


@wp.func
def cube_on_shelf(ctx: TaskContext, w: int) -> bool:
    """Bar standing on the shelf deck, released, for 20 consecutive steps (Place success)."""
    c = entity_pos(ctx, w, CUBE)
    d = entity_pos(ctx, w, DECK)
    ok = wp.length(wp.vec2(c[0] - d[0], c[1] - d[1])) <= SHELF_XY_TOL
    ok = ok and wp.abs(c[2] - (d[2] + SHELF_DZ)) <= SHELF_DZ_TOL
    ok = ok and entity_up_dot(ctx, w, CUBE) >= UPRIGHT_MIN and wp.abs(gripper_q(ctx, w)) <= GRIPPER_OPEN_TOL
    return held_for(ctx, w, 0, ok, PLACE_HOLD_STEPS)


@wp.func
def cube_dropped(ctx: TaskContext, w: int) -> bool:
    """Bar on the floor [failure]."""
    return entity_pos(ctx, w, CUBE)[2] < DROP_Z


@wp.func
def cube_tipped(ctx: TaskContext, w: int) -> bool:
    """Bar knocked over (its axis more than 60 deg from vertical) [failure]."""
    return entity_up_dot(ctx, w, CUBE) < TIPPED_UP_DOT


@wp.func
def grasped_cube(ctx: TaskContext, w: int) -> bool:
    """TCP at the bar with the gripper closed on it (subtask signal)."""
    return wp.length(entity_pos(ctx, w, CUBE) - tcp_pos(ctx, w)) < GRASP_DIST and gripper_q(ctx, w) > GRASP_GRIPPER_MIN
