"""Observation terms every G1 task can list: ``func(ctx, w, out, col)`` writes its columns."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, gripper_q, tcp_pose, write_transform
from newton_lab.task_api.cfg import ACTION_DIM, ARM_JOINTS, ROBOT_COORDS, ObsTermCfg


@wp.func
def last_action(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The action applied in the last step (action_dim)."""
    for j in range(ctx.actions.shape[1]):
        out[w, col + j] = ctx.actions[w, j]


@wp.func
def robot_joint_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Every robot coordinate in model order (robot_coords) [m | rad]."""
    for j in range(ctx.robot_coords):
        out[w, col + j] = ctx.joint_q[w * ctx.coords_per_world + j]


@wp.func
def robot_joint_vel(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Every robot DOF velocity in model order (robot_coords) [m/s | rad/s]."""
    for j in range(ctx.robot_coords):
        out[w, col + j] = ctx.joint_qd[w * ctx.dofs_per_world + j]


@wp.func
def arm_joint_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The controlled arm's joint positions (arm_joints) [rad]."""
    for j in range(ctx.arm_coords.shape[0]):
        out[w, col + j] = ctx.joint_q[w * ctx.coords_per_world + ctx.arm_coords[j]]


@wp.func
def gripper_pos(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Gripper master joint (1) [rad]."""
    out[w, col] = gripper_q(ctx, w)


@wp.func
def tcp_pose_obs(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """TCP pose (7): x, y, z, qx, qy, qz, qw, world frame."""
    write_transform(out, w, col, tcp_pose(ctx, w))


LAST_ACTION = ObsTermCfg(func=last_action, size=ACTION_DIM)
ROBOT_JOINT_POS = ObsTermCfg(func=robot_joint_pos, size=ROBOT_COORDS)
ROBOT_JOINT_VEL = ObsTermCfg(func=robot_joint_vel, size=ROBOT_COORDS)
ARM_JOINT_POS = ObsTermCfg(func=arm_joint_pos, size=ARM_JOINTS)
TCP_POSE = ObsTermCfg(func=tcp_pose_obs, size=7)
GRIPPER_POS = ObsTermCfg(func=gripper_pos, size=1)


def manipulation_observations(**objects: ObsTermCfg) -> dict[str, ObsTermCfg]:
    """The left-arm manipulation observation: last action, robot joints, TCP pose (7), gripper (1), then the
    task's object terms."""
    return {"actions": LAST_ACTION, "robot_joint_pos": ROBOT_JOINT_POS, "tcp_pose": TCP_POSE,
            "gripper_pos": GRIPPER_POS, **objects}
