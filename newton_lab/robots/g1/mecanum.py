"""The G1's mecanum base: the gains of its wheel radius and offsets, and the one formula (``robots.mecanum``) with
them on torch tensors (the packers' and tests' entry points).

The gains are ``lin = lin_scale / (sqrt(2) r)``, ``yaw = ang_scale / (2 sqrt(2) r (|wx| + |wy|))`` with
r = WHEEL_RADIUS [m], wx/wy = WHEEL_OFFSET_X/Y [m] (as on the reference platform); defaults give (7.0711, 10.0161).
"""

from __future__ import annotations

import torch

from .. import mecanum
from ..mecanum import MIX, twist_to_wheels, wheels_to_twist  # noqa: F401 - re-exported: the formula itself
from . import spec


def wheel_gains(*, lin_scale: float = 1.0, ang_scale: float = 1.0) -> tuple[float, float]:
    """The G1's mecanum gains ``(lin, yaw)``: wheel [rad/s] per base [m/s] and per base yaw [rad/s]."""
    return mecanum.wheel_gains(spec.WHEEL_RADIUS, spec.WHEEL_OFFSET_X, spec.WHEEL_OFFSET_Y, lin_scale=lin_scale,
                               ang_scale=ang_scale)


def twist_to_wheels_torch(twist: torch.Tensor, *, lin_scale: float = 1.0, ang_scale: float = 1.0) -> torch.Tensor:
    """(N, 3) base twists (vx, vy [m/s], wz [rad/s]) -> (N, 4) float32 wheel speeds [rad/s] of the G1, on the
    tensor's device."""
    return mecanum.twist_to_wheels_torch(twist, wheel_gains(lin_scale=lin_scale, ang_scale=ang_scale))


def wheels_to_twist_torch(wheels: torch.Tensor, *, lin_scale: float = 1.0, ang_scale: float = 1.0) -> torch.Tensor:
    """(N, 4) wheel speeds [rad/s] of the G1 -> (N, 3) float32 base twists."""
    return mecanum.wheels_to_twist_torch(wheels, wheel_gains(lin_scale=lin_scale, ang_scale=ang_scale))
