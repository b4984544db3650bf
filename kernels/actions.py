"""Action packing: kernels that map the (num_envs, action_dim) action tensor onto drive targets.

Per control step ``apply_actions`` writes every column to its joint's target (``control``); columns a row's
current phase does not own hold (position targets keep their current value, velocity targets become 0).
Per physics substep ``drive_base`` turns the four wheel-velocity columns into the planar base's velocity
targets through the mecanum kinematics (``robots.mecanum``, with the robot's gains), and ``drive_setpoints``
derives what the solver tracks (the drive) from the targets: equal to them, except that a velocity-limited joint's
setpoint moves toward its target at no more than its limit, with that velocity as the drive's velocity target.
Every column's processed action is ``clamp(scale * a, low, high)`` (:func:`processed_action`).
"""

from __future__ import annotations

import warp as wp

from ..robots.mecanum import wheels_to_twist

TARGET_POSITION = 0
"""Column writes an absolute position target (coordinate index): ``absolute`` and ``binary`` kinds."""
TARGET_VELOCITY = 1
"""Column writes a velocity target (DOF index): ``velocity`` kind."""
TARGET_RELATIVE = 2
"""Column adds its processed action to the current position target (coordinate index), which stays within
[target_low, target_high] (the joint's range): ``relative`` kind."""

KIND_CODE = {
    "absolute": TARGET_POSITION,
    "binary": TARGET_POSITION,
    "relative": TARGET_RELATIVE,
    "velocity": TARGET_VELOCITY,
}
"""Kernel code of each action kind (``robots.bound.ACTION_KINDS``)."""


@wp.func
def processed_action(
    actions: wp.array2d(dtype=float),
    w: int,
    c: int,
    scale: wp.array(dtype=float),
    low: wp.array(dtype=float),
    high: wp.array(dtype=float),
) -> float:
    """Column ``c`` of row ``w`` scaled and clipped: ``clamp(scale[c] * a, low[c], high[c])``."""
    return wp.clamp(scale[c] * actions[w, c], low[c], high[c])


@wp.kernel
def apply_actions(
    actions: wp.array2d(dtype=float),
    kind: wp.array(dtype=int),
    index: wp.array(dtype=int),
    scale: wp.array(dtype=float),
    low: wp.array(dtype=float),
    high: wp.array(dtype=float),
    target_low: wp.array(dtype=float),
    target_high: wp.array(dtype=float),
    owned: wp.array2d(dtype=bool),
    phase: wp.array(dtype=int),
    coords_per_world: int,
    dofs_per_world: int,
    target_q: wp.array(dtype=float),
    target_qd: wp.array(dtype=float),
):
    """Write column ``c`` of row ``w`` to its joint's target when the row's phase owns the column
    (``owned[phase, c]``); otherwise hold."""
    w, c = wp.tid()
    active = owned[phase[w], c]
    a = processed_action(actions, w, c, scale, low, high)
    k = kind[c]
    if k == TARGET_VELOCITY:
        if not active:
            a = 0.0
        target_qd[w * dofs_per_world + index[c]] = a
    elif active:
        i = w * coords_per_world + index[c]
        if k == TARGET_RELATIVE:
            target_q[i] = wp.clamp(target_q[i] + a, target_low[c], target_high[c])
        else:
            target_q[i] = a


@wp.kernel
def drive_base(
    actions: wp.array2d(dtype=float),
    wheel_col: int,
    scale: wp.array(dtype=float),
    low: wp.array(dtype=float),
    high: wp.array(dtype=float),
    owned: wp.array2d(dtype=bool),
    base_free: wp.array(dtype=bool),
    phase: wp.array(dtype=int),
    lin_gain: float,
    yaw_gain: float,
    base_dof: int,
    dofs_per_world: int,
    yaw_q: wp.array(dtype=float),
    yaw_stride: int,
    yaw_offset: int,
    target_qd: wp.array(dtype=float),
):
    """Wheel velocities (columns ``wheel_col .. +3``, [rad/s]) -> base twist -> planar base velocity targets.

    Un-mixes the wheel speeds with ``robots.mecanum.wheels_to_twist`` (the model has no rollers: the base
    is a planar joint) to the base-frame twist (vx, vy [m/s], wz [rad/s]) and rotates it into the world-frame
    x / y slides by the current yaw, ``yaw_q[w * yaw_stride + yaw_offset]`` (the env's coordinates, or MuJoCo-Warp's
    ``qpos`` between the substeps of a control step). Launched before every physics substep so the rotation follows
    the turning base. Rows whose phase does not own the wheels, or whose phase fixes the base, get a zero twist.
    """
    w = wp.tid()
    ph = phase[w]
    twist = wp.vec3(0.0, 0.0, 0.0)
    if owned[ph, wheel_col] and base_free[ph]:
        wheels = wp.vec4(
            processed_action(actions, w, wheel_col + 0, scale, low, high),
            processed_action(actions, w, wheel_col + 1, scale, low, high),
            processed_action(actions, w, wheel_col + 2, scale, low, high),
            processed_action(actions, w, wheel_col + 3, scale, low, high),
        )
        twist = wheels_to_twist(wheels, lin_gain, yaw_gain)
    yaw = yaw_q[w * yaw_stride + yaw_offset]
    c = wp.cos(yaw)
    s = wp.sin(yaw)
    d = w * dofs_per_world + base_dof
    target_qd[d + 0] = c * twist[0] - s * twist[1]
    target_qd[d + 1] = s * twist[0] + c * twist[1]
    target_qd[d + 2] = twist[2]


@wp.kernel
def drive_setpoints(
    target_q: wp.array(dtype=float),
    target_qd: wp.array(dtype=float),
    max_step: wp.array(dtype=float),
    coord_dof: wp.array(dtype=int),
    dof_limited: wp.array(dtype=bool),
    sim_dt: float,
    coords_per_world: int,
    dofs_per_world: int,
    drive_q: wp.array(dtype=float),
    drive_qd: wp.array(dtype=float),
):
    """One physics substep of the drive the solver tracks (launched over (num_envs, max(coords, dofs))).

    Thread (w, i) serves coordinate i and DOF i of row w. A coordinate with ``max_step[i] > 0`` (velocity
    limit x sim_dt) moves its setpoint ``drive_q`` toward ``target_q`` by at most that step and writes the step's
    velocity to its DOF's ``drive_qd`` (``coord_dof[i]``); every other coordinate / DOF copies its target.
    """
    w, i = wp.tid()
    if i < coords_per_world:
        k = w * coords_per_world + i
        m = max_step[i]
        if m > 0.0:
            err = target_q[k] - drive_q[k]
            step = wp.clamp(err, -m, m)
            if wp.abs(err) <= m:
                drive_q[k] = target_q[k]
            else:
                drive_q[k] = drive_q[k] + step
            drive_qd[w * dofs_per_world + coord_dof[i]] = step / sim_dt
        else:
            drive_q[k] = target_q[k]
    if i < dofs_per_world:
        if not dof_limited[i]:
            drive_qd[w * dofs_per_world + i] = target_qd[w * dofs_per_world + i]


@wp.kernel
def sync_setpoints(mask: wp.array(dtype=bool), target_q: wp.array2d(dtype=float), drive_q: wp.array2d(dtype=float)):
    """Setpoints of the masked (just reset) rows jump to their targets (launched over (num_envs, coords))."""
    w, i = wp.tid()
    if mask[w]:
        drive_q[w, i] = target_q[w, i]
