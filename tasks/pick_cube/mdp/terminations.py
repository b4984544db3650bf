"""PickCube predicates (reference thresholds)."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, entity_pos, gripper_q, tcp_pos

from ..scene import BLUE_BLOCK, CUBE

RELEASE_XY_TOL = 0.08
"""Cube centre within this xy distance of the block centre [m]."""
RELEASE_DZ = 0.035
"""Expected cube-above-block height: block half height 0.01 + cube half size 0.025 [m]."""
RELEASE_DZ_TOL = 0.03
GRIPPER_OPEN_TOL = 0.05
"""Gripper counts as open at or below this [rad]."""
GRASP_DIST = 0.06
"""TCP within this distance of the cube centre for a grasp [m]."""
GRASP_GRIPPER_MIN = 0.3
"""Gripper closed on the cube. The reference's 1.2 equals the closed target and never fires on a cube;
the authored fingers stop on a 5 cm cube near 0.67 rad, so 0.3 separates open from closed-on-object."""


@wp.func
def released_on_blue_block(ctx: TaskContext, w: int) -> bool:
    """Cube resting on the blue block with the gripper open (episode success)."""
    c = entity_pos(ctx, w, CUBE)
    b = entity_pos(ctx, w, BLUE_BLOCK)
    dxy = wp.length(wp.vec2(c[0] - b[0], c[1] - b[1]))
    dz = c[2] - b[2] - RELEASE_DZ
    return dxy < RELEASE_XY_TOL and wp.abs(dz) < RELEASE_DZ_TOL and wp.abs(gripper_q(ctx, w)) <= GRIPPER_OPEN_TOL


@wp.func
def grasped_cube(ctx: TaskContext, w: int) -> bool:
    """TCP at the cube with the gripper closed on it (Mimic subtask signal)."""
    d = wp.length(entity_pos(ctx, w, CUBE) - tcp_pos(ctx, w))
    return d < GRASP_DIST and gripper_q(ctx, w) > GRASP_GRIPPER_MIN


@wp.func
def cube_dropped(ctx: TaskContext, w: int) -> bool:
    """Cube fell off the table (below the table top by more than its size) [failure]."""
    return entity_pos(ctx, w, CUBE)[2] < 0.05
