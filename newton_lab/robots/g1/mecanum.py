"""The G1's mecanum base: the gains of its wheel radius and offsets for the one formula (``robots.mecanum``), read
through ``RobotBinding.wheel_gains`` (``robots.g1.robot.G1``).

The gains are ``lin = lin_scale / (sqrt(2) r)``, ``yaw = ang_scale / (2 sqrt(2) r (|wx| + |wy|))`` with
r = WHEEL_RADIUS [m], wx/wy = WHEEL_OFFSET_X/Y [m] (as on the reference platform); defaults give (7.0711, 10.0161).
"""

from __future__ import annotations

from .. import mecanum
from . import spec


def wheel_gains(*, lin_scale: float = 1.0, ang_scale: float = 1.0) -> tuple[float, float]:
    """The G1's mecanum gains ``(lin, yaw)``: wheel [rad/s] per base [m/s] and per base yaw [rad/s]."""
    return mecanum.wheel_gains(
        spec.WHEEL_RADIUS, spec.WHEEL_OFFSET_X, spec.WHEEL_OFFSET_Y, lin_scale=lin_scale, ang_scale=ang_scale
    )
