"""Observation terms every G1 task can list: ``func(ctx, w, out, col)`` writes its columns."""

from __future__ import annotations

import warp as wp

from newton_lab.task_api.cfg import ObsTermCfg
from newton_lab.kernels.context import TaskContext, gripper_q, tcp_pose, write_transform

ROBOT_COORDS = 34
"""Coordinates of the authored G1 (base x/y/yaw, wheels, legs, head, arms, grippers, fingers)."""


@wp.func
def last_action(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The action applied in the last step (action_dim)."""
    for j in range(ctx.actions.shape[1]):
        out[w, col + j] = ctx.actions[w, j]


@wp.func
def robot_joint_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Every robot coordinate in model order (34) [m | rad]."""
    for j in range(ROBOT_COORDS):
        out[w, col + j] = ctx.joint_q[w * ctx.coords_per_world + j]


@wp.func
def robot_joint_vel(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Every robot DOF velocity in model order (34) [m/s | rad/s]."""
    for j in range(ROBOT_COORDS):
        out[w, col + j] = ctx.joint_qd[w * ctx.dofs_per_world + j]


@wp.func
def arm_joint_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The controlled arm's 7 joint positions [rad]."""
    for j in range(7):
        out[w, col + j] = ctx.joint_q[w * ctx.coords_per_world + ctx.arm_coords[j]]


@wp.func
def gripper_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Gripper master joint (1) [rad]."""
    out[w, col] = gripper_q(ctx, w)


@wp.func
def tcp_pose_obs(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """TCP pose (7): x, y, z, qx, qy, qz, qw, world frame."""
    write_transform(out, w, col, tcp_pose(ctx, w))


def manipulation_observations(objects: list[ObsTermCfg]) -> list[ObsTermCfg]:
    """The left-arm manipulation observation: last action (8), robot joints (34), TCP pose (7), gripper (1),
    then the task's object terms."""
    return [
        ObsTermCfg(name="actions", func=last_action, dim=8),
        ObsTermCfg(name="robot_joint_pos", func=robot_joint_pos, dim=ROBOT_COORDS),
        ObsTermCfg(name="tcp_pose", func=tcp_pose_obs, dim=7),
        ObsTermCfg(name="gripper_pos", func=gripper_pos, dim=1),
        *objects,
    ]
