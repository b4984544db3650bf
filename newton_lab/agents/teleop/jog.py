"""Cartesian TCP jog: a device's cumulative TCP offset -> arm joint targets through the batched IK
(the robot's ``RobotBinding.kinematics``), warm-started from the last solution and solved only when the
offset changes. Joint targets move towards the solution at most ``max_joint_step`` per control step, as the
expert planner's waypoints do, so a long jump of the target never throws the arm."""

from __future__ import annotations

import numpy as np
import warp as wp

from ...robots.quaternions import quat_mul


def yaw_quat(yaw: float) -> np.ndarray:
    """(1, 4) xyzw rotation by ``yaw`` [rad] about the world z axis."""
    return np.array([[0.0, 0.0, np.sin(yaw / 2.0), np.cos(yaw / 2.0)]])


class TcpJog:
    """Per-arm jog state of every env row: the TCP pose at the episode start, the last solved joints."""

    def __init__(self, env, arm: str = "left", *, max_joint_step: float = 0.05, ik_iterations: int = 24):
        self.arm, self.max_joint_step, self.ik_iterations = arm, float(max_joint_step), ik_iterations
        self._coords = env.joints.coords(env.robot.arm(arm).joints)
        self._robot_coords = env.joints.robot_coords
        self._kin = env.robot.kinematics(env.num_envs, device=env.device, arm=arm)
        self.start: np.ndarray | None = None
        """(N, 7) TCP pose at the episode start (world; xyzw)."""
        self._offset: np.ndarray | None = None
        self._solution: np.ndarray | None = None
        self._command: np.ndarray | None = None
        self.error = 0.0
        """TCP position error of the last IK solution [m] (forward kinematics)."""

    def _robot_q(self, env) -> np.ndarray:
        q = wp.to_torch(env.state.joint_q).view(env.num_envs, -1)[:, : self._robot_coords]
        return q.detach().cpu().numpy().astype(np.float32)

    def reset(self, env) -> None:
        """Start a new episode: the jog origin is the TCP pose now."""
        self.start = env.buffers.tcp_pose.detach().cpu().numpy().astype(np.float64)
        q = self._robot_q(env)
        self._offset = np.zeros(4)
        self._command = q[:, self._coords].astype(np.float64)
        pos, quat = self.target_pose(self._offset)  # the start pose itself: warms (captures) the IK solve
        self._solution = self._kin.solve(q, pos, quat, iterations=self.ik_iterations)[:, self._coords].astype(
            np.float64
        )
        self.error = 0.0

    def target_pose(self, offset) -> tuple[np.ndarray, np.ndarray]:
        """World TCP position (N, 3) and xyzw orientation (N, 4) for offset (dx, dy, dz, dyaw)."""
        off = np.asarray(offset, dtype=np.float64)
        pos = self.start[:, :3] + off[:3]
        quat = quat_mul(np.repeat(yaw_quat(off[3]), len(pos), axis=0), self.start[:, 3:7])
        return pos, quat

    def __call__(self, env, offset) -> np.ndarray:
        """Arm joint targets (N, 7) [rad] for the cumulative ``offset``; call once per control step."""
        if self.start is None:
            self.reset(env)
        offset = np.asarray(offset, dtype=np.float64)
        if not np.array_equal(offset, self._offset):
            seed = self._robot_q(env)
            seed[:, self._coords] = self._solution
            pos, quat = self.target_pose(offset)
            q = self._kin.solve(seed, pos, quat, iterations=self.ik_iterations)
            self._solution = q[:, self._coords].astype(np.float64)
            self.error = float(np.linalg.norm(self._kin.tcp_poses(q)[:, :3] - pos, axis=1).max())
            self._offset = offset
        step = np.clip(self._solution - self._command, -self.max_joint_step, self.max_joint_step)
        self._command = self._command + step
        return self._command
