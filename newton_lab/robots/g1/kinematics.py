"""Batched TCP kinematics of the G1 arm: inverse kinematics with ``newton.ik`` and forward kinematics
with ``newton.eval_fk``, for many independent problems at once (one per env row, or per recorded frame).

Robot coordinate vectors are the robot's own 34 coordinates (the first 34 of every env world).
Poses are (x, y, z, qx, qy, qz, qw), world frame.
"""

from __future__ import annotations

import newton
import newton.ik as ik
import numpy as np
import warp as wp

from . import spec
from .model import JointIndex, add_g1


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (3,) or (R, 3) by (R, 4) xyzw quaternions."""
    u, w = q[:, :3], q[:, 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (R, 4) xyzw quaternions."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=1,
    )


def _robot_builder() -> tuple[newton.ModelBuilder, JointIndex]:
    b = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(b)
    add_g1(b)
    return b, JointIndex.from_builder(b)


class TcpKinematics:
    """IK and FK of one arm's TCP for ``n`` problems on ``device``."""

    def __init__(self, n: int, *, device, arm: str = "left"):
        self.n = n
        self.device = wp.get_device(device)
        self.arm = arm
        arm_joints = spec.LEFT_ARM_JOINTS if arm == "left" else spec.RIGHT_ARM_JOINTS
        with wp.ScopedDevice(self.device):
            b, self.joints = _robot_builder()
            self.robot_coords = b.joint_coord_count
            self.arm_coords = [self.joints.coord[j] for j in arm_joints]
            self._link = self.joints.body[spec.END_EFFECTOR_LINK[arm]]
            self._bodies = b.body_count
            model = b.finalize(device=self.device)
            self._pos = ik.IKObjectivePosition(
                link_index=self._link,
                link_offset=wp.vec3(*spec.TCP_OFFSET_POS),
                target_positions=wp.zeros(n, dtype=wp.vec3),
            )
            self._rot = ik.IKObjectiveRotation(
                link_index=self._link,
                link_offset_rotation=wp.quat(*spec.TCP_OFFSET_QUAT),
                target_rotations=wp.array(np.tile(spec.TOP_DOWN_TCP_QUAT, (n, 1)), dtype=wp.vec4),
            )
            limits = ik.IKObjectiveJointLimit(
                joint_limit_lower=model.joint_limit_lower, joint_limit_upper=model.joint_limit_upper, weight=10.0
            )
            mask = np.zeros(model.joint_dof_count, dtype=bool)
            mask[[self.joints.dof[j] for j in arm_joints]] = True
            self._ik = ik.IKSolver(
                model=model,
                n_problems=n,
                objectives=[self._pos, self._rot, limits],
                lambda_initial=0.1,
                jacobian_mode=ik.IKJacobianType.ANALYTIC,
                joint_dof_mask=wp.array(mask, dtype=wp.bool),
            )
            self._q = wp.zeros((n, self.robot_coords), dtype=wp.float32)
            fk = newton.ModelBuilder()
            newton.solvers.SolverMuJoCo.register_custom_attributes(fk)
            fk.replicate(b, n)
            self._fk_model = fk.finalize(device=self.device)
            self._fk_state = self._fk_model.state()

    def solve(self, q_seed: np.ndarray, pos: np.ndarray, quat: np.ndarray, *, iterations: int = 48) -> np.ndarray:
        """Arm IK for every problem: ``q_seed`` (n, 34) robot coordinates (base / legs / other joints are
        kept), target TCP ``pos`` (n, 3) and ``quat`` (n, 4) xyzw. Returns the solved (n, 34) coordinates."""
        self._pos.set_target_positions(wp.array(np.asarray(pos, np.float32), dtype=wp.vec3, device=self.device))
        self._rot.set_target_rotations(wp.array(np.asarray(quat, np.float32), dtype=wp.vec4, device=self.device))
        self._q.assign(np.asarray(q_seed, dtype=np.float32))
        self._ik.step(self._q, self._q, iterations=iterations)
        return self._q.numpy()

    def tcp_poses(self, q: np.ndarray) -> np.ndarray:
        """TCP poses (m, 7) of ``m <= n`` robot coordinate rows ``q`` (m, 34)."""
        q = np.asarray(q, dtype=np.float32)
        m = q.shape[0]
        full = np.zeros((self.n, self.robot_coords), dtype=np.float32)
        full[:m] = q
        self._fk_state.joint_q.assign(full.reshape(-1))
        newton.eval_fk(self._fk_model, self._fk_state.joint_q, self._fk_state.joint_qd, self._fk_state)
        link = self._fk_state.body_q.numpy().reshape(self.n, self._bodies, 7)[:m, self._link].astype(np.float64)
        tcp_rot = np.tile(np.asarray(spec.TCP_OFFSET_QUAT, dtype=np.float64), (m, 1))
        pos = link[:, :3] + quat_rotate(link[:, 3:7], np.asarray(spec.TCP_OFFSET_POS, dtype=np.float64))
        return np.concatenate([pos, quat_mul(link[:, 3:7], tcp_rot)], axis=1)
