"""LiftCube predicates."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos, gripper_q, held_for, tcp_pos

from ..scene import CUBE, CUBE_INIT

LIFT_HEIGHT = 0.10
"""Success: cube centre this far above its resting height [m]."""
LIFTED_Z = wp.constant(CUBE_INIT[2] + LIFT_HEIGHT)
HOLD_STEPS = 5
"""... held for this many consecutive control steps."""
GRASP_DIST = 0.06
"""TCP within this distance of the cube centre [m]."""
GRASP_GRIPPER_MIN = 0.3
"""Gripper closed on the cube (the authored fingers stop on a 5 cm cube near 0.67 rad) [rad]."""
DROPPED_Z = 0.05
"""Cube below this has left the table [m]."""


@wp.func
def grasped_cube(ctx: TaskContext, w: int) -> bool:
    """TCP at the cube with the gripper closed on it (subtask signal)."""
    d = wp.length(entity_pos(ctx, w, CUBE) - tcp_pos(ctx, w))
    return d < GRASP_DIST and gripper_q(ctx, w) > GRASP_GRIPPER_MIN


@wp.func
def cube_lifted(ctx: TaskContext, w: int) -> bool:
    """Cube grasped and at least 10 cm above its start for 5 consecutive steps (episode success)."""
    up = entity_pos(ctx, w, CUBE)[2] >= LIFTED_Z
    return held_for(ctx, w, 0, up and grasped_cube(ctx, w), HOLD_STEPS)


@wp.func
def cube_dropped(ctx: TaskContext, w: int) -> bool:
    """Cube fell off the table [failure]."""
    return entity_pos(ctx, w, CUBE)[2] < DROPPED_Z
