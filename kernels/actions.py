"""Action packing: kernels that map the (num_envs, action_dim) action tensor onto drive targets.

``apply_actions`` writes every column to its joint's target; columns a row's current phase does not own
hold (position targets keep their current value, velocity targets become 0). ``drive_base`` turns the
four wheel-velocity columns into the planar base's velocity targets through the mecanum kinematics.
"""

from __future__ import annotations

import warp as wp

TARGET_POSITION = 0
"""Column writes an absolute position target (coordinate index)."""
TARGET_VELOCITY = 1
"""Column writes a velocity target (DOF index)."""


@wp.kernel
def apply_actions(
    actions: wp.array2d(dtype=float),
    kind: wp.array(dtype=int),
    index: wp.array(dtype=int),
    low: wp.array(dtype=float),
    high: wp.array(dtype=float),
    owned: wp.array2d(dtype=bool),
    phase: wp.array(dtype=int),
    coords_per_world: int,
    dofs_per_world: int,
    target_q: wp.array(dtype=float),
    target_qd: wp.array(dtype=float),
):
    """Write column ``c`` of row ``w`` (clipped to [low, high]) to its joint's drive target when the row's
    phase owns the column (``owned[phase, c]``); otherwise hold."""
    w, c = wp.tid()
    active = owned[phase[w], c]
    a = wp.clamp(actions[w, c], low[c], high[c])
    if kind[c] == TARGET_POSITION:
        if active:
            target_q[w * coords_per_world + index[c]] = a
    else:
        if not active:
            a = 0.0
        target_qd[w * dofs_per_world + index[c]] = a


@wp.kernel
def drive_base(
    actions: wp.array2d(dtype=float),
    wheel_col: int,
    low: wp.array(dtype=float),
    high: wp.array(dtype=float),
    owned: wp.array2d(dtype=bool),
    base_free: wp.array(dtype=bool),
    phase: wp.array(dtype=int),
    lin_gain: float,
    yaw_gain: float,
    base_coord: int,
    base_dof: int,
    coords_per_world: int,
    dofs_per_world: int,
    joint_q: wp.array(dtype=float),
    target_qd: wp.array(dtype=float),
):
    """Wheel velocities (columns ``wheel_col .. +3``, [rad/s]) -> base twist -> planar base velocity targets.

    Inverts the reference mixing ``w = (-vx+vy, -vx-vy, vx-vy, vx+vy) * lin_gain + wz * yaw_gain`` (wheel 1..4)
    to the base-frame twist (vx, vy [m/s], wz [rad/s]) and rotates it into the world-frame x / y slides by the
    current yaw. Launched before every physics substep so the rotation follows the turning base. Rows whose
    phase does not own the wheels, or whose phase fixes the base, get a zero twist.
    """
    w = wp.tid()
    ph = phase[w]
    vx = float(0.0)
    vy = float(0.0)
    wz = float(0.0)
    if owned[ph, wheel_col] and base_free[ph]:
        w1 = wp.clamp(actions[w, wheel_col + 0], low[wheel_col + 0], high[wheel_col + 0])
        w2 = wp.clamp(actions[w, wheel_col + 1], low[wheel_col + 1], high[wheel_col + 1])
        w3 = wp.clamp(actions[w, wheel_col + 2], low[wheel_col + 2], high[wheel_col + 2])
        w4 = wp.clamp(actions[w, wheel_col + 3], low[wheel_col + 3], high[wheel_col + 3])
        vx = (-w1 - w2 + w3 + w4) / (4.0 * lin_gain)
        vy = (w1 - w2 - w3 + w4) / (4.0 * lin_gain)
        wz = (w1 + w2 + w3 + w4) / (4.0 * yaw_gain)
    yaw = joint_q[w * coords_per_world + base_coord + 2]
    c = wp.cos(yaw)
    s = wp.sin(yaw)
    d = w * dofs_per_world + base_dof
    target_qd[d + 0] = c * vx - s * vy
    target_qd[d + 1] = s * vx + c * vy
    target_qd[d + 2] = wz
