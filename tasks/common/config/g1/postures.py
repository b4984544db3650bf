"""Robot postures and placements the G1 tasks start from or move through (env frame, [rad], [m]).

Re-derived for the authored G1 kinematics with the reference's intent; they belong to the tasks, not to the
robot spec (which keeps only robot facts: joints, limits, TCP, mounts).
"""

from __future__ import annotations

from newton_lab.robots.g1 import spec

MANIPULATION_ROOT_POS = (-1.0, 0.0, 0.0)
"""Robot root of the fixed-base table-top tasks [m]."""

TABLE_TOP_LEFT_ARM = (-0.9451, 0.0833, 0.0819, 2.0675, 0.0449, 0.4443, -0.0746)
"""Left arm at reset of the table-top tasks: TCP top-down at (-0.50, 0.25, 0.35), above the table's near half."""
TABLE_TOP_HEAD = (0.0, 0.45)
"""Head (yaw, pitch) looking down at the table [rad]."""
LEVEL_HEAD = (0.0, 0.0)
"""Head looking straight ahead [rad]."""

CARRY_LEFT_ARM = (1.5646, -0.6287, 0.6743, -2.2645, 0.8960, 0.9327, 0.0153)
"""Carry / ready posture of the shelf tasks: elbow down, hand raised in front of the torso, gripper horizontal
pointing forward (TCP at (0.65, 0.0, 0.66) in the base frame, xyzw (1, 0, 0, 0)). The held object sits on the
base's centre line, so facing a shelf it enters the cell between the side panels, and it hangs clear of a
0.325 m table."""
SIDE_GRASP_TCP_QUAT = (1.0, 0.0, 0.0, 0.0)
"""Horizontal TCP pointing along the base's +x (approach), fingers closing along y, xyzw."""
SHELF_HEAD = (0.0, 0.25)
"""Head (yaw, pitch) of the shelf tasks [rad]."""

LEG_LIFT_STEP = 0.2
"""Body-height step for the shelf's upper row: legs (s, 3s, 2s, 0, 0) [rad]."""
UPPER_ROW_LEGS = spec.leg_lift(LEG_LIFT_STEP)
"""Leg posture for placing into the shelf's upper row [rad] (5)."""
