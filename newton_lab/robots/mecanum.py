"""Mecanum wheel kinematics: the one formula, in Warp, for any four-wheel mecanum base.

Wheel speeds (wheel1..wheel4 [rad/s]) and the base-frame twist (vx, vy [m/s], wz [rad/s]) are related by one
mixing matrix ``MIX`` (4 x 3, entries +-1) and the gains of :func:`wheel_gains` (as on the reference platform)::

    wheels = MIX @ (lin * vx, lin * vy, yaw * wz)

``MIX``'s columns are orthogonal with squared norm 4, so the exact (least-squares) inverse is
``twist = (MIX^T @ wheels / 4) / (lin, lin, yaw)``. :func:`twist_to_wheels` and :func:`wheels_to_twist` are
the ``@wp.func`` pair every user calls: the env's ``drive_base`` kernel (wheel columns -> planar base
velocity), and, through :func:`twist_to_wheels_torch` / :func:`wheels_to_twist_torch`, the nav and teleop
agents on torch tensors. A robot's gains come from its wheel radius and offsets
(``RobotBinding.wheel_gains``; the G1's: ``robots.g1.mecanum``).
"""

from __future__ import annotations

import math

import torch
import warp as wp

mat43 = wp.types.matrix(shape=(4, 3), dtype=wp.float32)

MIX = wp.constant(
    mat43(
        -1.0,
        1.0,
        1.0,  # wheel1 = -vx + vy + wz
        -1.0,
        -1.0,
        1.0,  # wheel2 = -vx - vy + wz
        1.0,
        -1.0,
        1.0,  # wheel3 = vx - vy + wz
        1.0,
        1.0,
        1.0,  # wheel4 = vx + vy + wz
    )
)
"""Wheel i's signs for (vx, vy, wz), rows wheel1..wheel4 (each term scaled by its gain)."""


def wheel_gains(
    radius: float, offset_x: float, offset_y: float, *, lin_scale: float = 1.0, ang_scale: float = 1.0
) -> tuple[float, float]:
    """Mecanum gains ``(lin, yaw)``: wheel [rad/s] per base [m/s] and per base yaw [rad/s].

    ``lin = lin_scale / (sqrt(2) r)``, ``yaw = ang_scale / (2 sqrt(2) r (|wx| + |wy|))`` with wheel radius
    ``r`` [m] and the wheels' offsets ``wx`` / ``wy`` [m] from the base centre.
    """
    lin = lin_scale / (math.sqrt(2.0) * radius)
    yaw = ang_scale / (2.0 * math.sqrt(2.0) * radius * (abs(offset_x) + abs(offset_y)))
    return lin, yaw


@wp.func
def twist_to_wheels(twist: wp.vec3, lin_gain: float, yaw_gain: float) -> wp.vec4:
    """Base twist (vx, vy [m/s], wz [rad/s]) -> wheel speeds wheel1..wheel4 [rad/s]."""
    return MIX @ wp.vec3(twist[0] * lin_gain, twist[1] * lin_gain, twist[2] * yaw_gain)


@wp.func
def wheels_to_twist(wheels: wp.vec4, lin_gain: float, yaw_gain: float) -> wp.vec3:
    """Wheel speeds wheel1..wheel4 [rad/s] -> base twist (vx, vy [m/s], wz [rad/s]); exact inverse of
    :func:`twist_to_wheels` (``MIX^T MIX = 4 I``)."""
    s = wp.transpose(MIX) @ wheels
    return wp.vec3(s[0] / (4.0 * lin_gain), s[1] / (4.0 * lin_gain), s[2] / (4.0 * yaw_gain))


@wp.kernel
def twist_to_wheels_kernel(
    twist: wp.array(dtype=wp.vec3), lin_gain: float, yaw_gain: float, wheels: wp.array(dtype=wp.vec4)
):
    i = wp.tid()
    wheels[i] = twist_to_wheels(twist[i], lin_gain, yaw_gain)


@wp.kernel
def wheels_to_twist_kernel(
    wheels: wp.array(dtype=wp.vec4), lin_gain: float, yaw_gain: float, twist: wp.array(dtype=wp.vec3)
):
    i = wp.tid()
    twist[i] = wheels_to_twist(wheels[i], lin_gain, yaw_gain)


def _map_rows(kernel, rows: torch.Tensor, width_in: int, width_out: int, lin: float, yaw: float) -> torch.Tensor:
    """Run ``kernel`` over the rows of a float32 (N, width_in) tensor on its own device; returns (N, width_out)."""
    vec_in, vec_out = (wp.vec3, wp.vec4) if width_in == 3 else (wp.vec4, wp.vec3)
    src = rows.detach().to(torch.float32).reshape(-1, width_in).contiguous()
    out = torch.empty(src.shape[0], width_out, dtype=torch.float32, device=src.device)
    if src.shape[0] == 0:
        return out
    wp.init()  # no-op once Warp is up (an agent may be the first Warp user of the process)
    device = wp.device_from_torch(src.device)
    stream = wp.stream_from_torch(src.device) if device.is_cuda else None
    wp.launch(
        kernel,
        dim=src.shape[0],
        inputs=[wp.from_torch(src, dtype=vec_in), float(lin), float(yaw)],
        outputs=[wp.from_torch(out, dtype=vec_out)],
        device=device,
        stream=stream,
    )
    return out


def twist_to_wheels_torch(twist: torch.Tensor, gains: tuple[float, float]) -> torch.Tensor:
    """(N, 3) base twists (vx, vy [m/s], wz [rad/s]) -> (N, 4) float32 wheel speeds [rad/s] through
    :func:`twist_to_wheels` with ``gains`` ``(lin, yaw)``, on the tensor's device."""
    return _map_rows(twist_to_wheels_kernel, twist, 3, 4, *gains)


def wheels_to_twist_torch(wheels: torch.Tensor, gains: tuple[float, float]) -> torch.Tensor:
    """(N, 4) wheel speeds [rad/s] -> (N, 3) float32 base twists through :func:`wheels_to_twist`."""
    return _map_rows(wheels_to_twist_kernel, wheels, 4, 3, *gains)
