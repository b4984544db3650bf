"""StackCube predicates (reference thresholds)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos, gripper_q, tcp_pos

from ..scene import CUBE_1, CUBE_2, CUBE_3

GRASP_DIST = 0.06
"""TCP within this distance of the cube centre [m]."""
GRIPPER_THRESHOLD = 0.10
"""Gripper counts as closed above this [rad]."""
STACK_XY_TOL = 0.04
STACK_DZ = 0.05
"""Cube size: centre-to-centre height of a stacked pair [m]."""
STACK_DZ_TOL = 0.006
GRIPPER_OPEN_TOL = 0.01
"""Gripper counts as open at or below this [rad] (the master rests on its 0 limit when open)."""
DROP_Z = 0.05
"""A cube centre below this fell off the table (top at 0.10) [m]."""


@wp.func
def _grasped(ctx: TaskContext, w: int, k: int) -> bool:
    d = wp.length(entity_pos(ctx, w, k) - tcp_pos(ctx, w))
    return d < GRASP_DIST and wp.abs(gripper_q(ctx, w)) > GRIPPER_THRESHOLD


@wp.func
def _on(ctx: TaskContext, w: int, top: int, bottom: int) -> bool:
    a = entity_pos(ctx, w, top)
    b = entity_pos(ctx, w, bottom)
    dxy = wp.length(wp.vec2(a[0] - b[0], a[1] - b[1]))
    return dxy < STACK_XY_TOL and wp.abs(a[2] - b[2] - STACK_DZ) < STACK_DZ_TOL


@wp.func
def _open(ctx: TaskContext, w: int) -> bool:
    return wp.abs(gripper_q(ctx, w)) <= GRIPPER_OPEN_TOL


@wp.func
def cube_2_grasped(ctx: TaskContext, w: int) -> bool:
    return _grasped(ctx, w, CUBE_2)


@wp.func
def cube_3_grasped(ctx: TaskContext, w: int) -> bool:
    return _grasped(ctx, w, CUBE_3)


@wp.func
def cube_2_on_cube_1(ctx: TaskContext, w: int) -> bool:
    """cube_2 stacked on cube_1 and released."""
    return _on(ctx, w, CUBE_2, CUBE_1) and _open(ctx, w)


@wp.func
def cube_3_on_cube_2(ctx: TaskContext, w: int) -> bool:
    """cube_3 stacked on cube_2 and released."""
    return _on(ctx, w, CUBE_3, CUBE_2) and _open(ctx, w)


@wp.func
def stack_success(ctx: TaskContext, w: int) -> bool:
    """The full three-cube stack, released (episode success)."""
    return _on(ctx, w, CUBE_2, CUBE_1) and _on(ctx, w, CUBE_3, CUBE_2) and _open(ctx, w)


@wp.func
def cube_dropping(ctx: TaskContext, w: int) -> bool:
    """Any cube fell off the table [failure]."""
    return (entity_pos(ctx, w, CUBE_1)[2] < DROP_Z or entity_pos(ctx, w, CUBE_2)[2] < DROP_Z
            or entity_pos(ctx, w, CUBE_3)[2] < DROP_Z)
