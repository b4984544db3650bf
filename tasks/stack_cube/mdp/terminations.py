"""StackCube predicates: the generic terms (``tasks.common.terminations``) with the reference's thresholds."""

from __future__ import annotations

from newton_lab.tasks.common.terminations import all_of, any_of, dropped, grasped, gripper_open, resting_on

from ..scene import CUBES

GRIPPER_CLOSED_MIN = 0.10
"""Gripper counts as closed (on a cube) above this [rad]."""
STACK_XY_TOL = 0.04
"""A stacked cube's centre within this xy distance of the one below [m] ..."""
STACK_DZ = 0.05
"""... and this (the cube size) above it [m] ..."""
STACK_DZ_TOL = 0.006
"""... within this [m]."""
GRIPPER_OPEN_TOL = 0.01
"""Gripper counts as open at or below this [rad] (the master rests on its 0 limit when open)."""
DROP_Z = 0.05
"""A cube centre below this fell off the table (top at 0.10) [m]."""


def grasped_cube(cube: str):
    """TCP within 6 cm of ``cube`` with the gripper closed past 0.1 rad."""
    return grasped(entity=cube, gripper_min=GRIPPER_CLOSED_MIN)


def stacked(top: str, bottom: str):
    """``top`` resting on ``bottom`` (whatever the gripper does)."""
    return resting_on(entity=top, target=bottom, height=STACK_DZ, xy_tol=STACK_XY_TOL, z_tol=STACK_DZ_TOL)


def stacked_and_released(top: str, bottom: str):
    """``top`` stacked on ``bottom`` with the gripper open (subtask signal)."""
    return all_of(terms=(stacked(top, bottom), gripper_open(tol=GRIPPER_OPEN_TOL)))


def stack_success():
    """The full three-cube stack, released (episode success)."""
    return all_of(terms=(stacked("cube_2", "cube_1"), stacked("cube_3", "cube_2"), gripper_open(tol=GRIPPER_OPEN_TOL)))


def cube_dropping():
    """Any cube fell off the table [failure]."""
    return any_of(terms=tuple(dropped(entity=c, below_z=DROP_Z) for c in CUBES))
