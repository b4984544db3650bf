"""Batched TCP kinematics of the G1 arm: inverse kinematics with ``newton.ik`` and forward kinematics
with ``newton.eval_fk``, for many independent problems at once (one per env row, or per recorded frame).

Robot coordinate vectors are the robot's own 34 coordinates (the first 34 of every env world).
Poses are (x, y, z, qx, qy, qz, qw), world frame.
"""

from __future__ import annotations

from typing import Any

import newton
import newton.ik as ik
import numpy as np
import torch
import warp as wp

from ..quaternions import quat_mul, quat_rotate
from . import spec
from .model import JointIndex, build_g1

__all__ = ["TcpKinematics", "quat_mul", "quat_rotate"]


def _robot_builder(weld: dict[str, float] | None = None) -> tuple[newton.ModelBuilder, JointIndex]:
    b = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(b)
    return b, build_g1(b, weld)


def chain_joints(arm: str) -> tuple[str, ...]:
    """The joints that move ``arm``'s TCP: the planar base, the legs and the arm (every other joint, the head, the
    other arm, the grippers and the wheels, leaves that TCP where it is)."""
    return spec.BASE_PLANAR_JOINTS + spec.LEG_JOINTS + spec.JOINT_GROUPS[f"{arm}_arm"]


class _Solve:
    """One IK problem size: target and seed buffers, and the solve (targets copied in, ``iterations`` LM steps)
    captured as a graph per iteration count after its first eager run. The LM solver launches ~16 small
    kernels per iteration, so an eager 48-iteration solve is ~800 launches, bound by launch overhead."""

    def __init__(self, pos, rot, solver, k: int, coords: int) -> None:
        self.pos, self.rot, self.solver = pos, rot, solver
        self.pos_in, self.rot_in = wp.zeros(k, dtype=wp.vec3), wp.zeros(k, dtype=wp.vec4)
        self.q = wp.zeros((k, coords), dtype=wp.float32)
        self.graphs: dict[int, Any] = {}

    def _body(self, iterations: int) -> None:
        self.pos.set_target_positions(self.pos_in)
        self.rot.set_target_rotations(self.rot_in)
        self.solver.step(self.q, self.q, iterations=iterations)

    def run(self, q_seed: np.ndarray, pos: np.ndarray, quat: np.ndarray, iterations: int) -> np.ndarray:
        def inputs() -> None:
            self.pos_in.assign(pos)
            self.rot_in.assign(quat)
            self.q.assign(q_seed)

        inputs()
        if iterations not in self.graphs:
            self._body(iterations)  # compiles the kernels before the capture
            self.graphs[iterations] = self._capture(iterations)
            inputs()  # the result comes from one run from the seed, whatever the capture executed
        graph = self.graphs[iterations]
        if graph is not None:
            wp.capture_launch(graph)
        else:
            self._body(iterations)
        return self.q.numpy().copy()  # (on the CPU numpy() is a view of the buffer the next solve overwrites)

    def _capture(self, iterations: int):
        try:
            with wp.ScopedCapture() as cap:
                self._body(iterations)
        except Exception:  # pragma: no cover - depends on the Warp build; eager solves stay correct
            return None
        return cap.graph


class TcpKinematics:
    """IK and FK of one arm's TCP for ``n`` problems on ``device``. Coordinates in and out are the whole robot's
    (``robot_coords``); inside, the solves and forward kinematics run on the robot with every joint off the TCP's
    chain welded (``chain_joints``: 15 degrees of freedom instead of 34), which gives the same TCP for the same
    chain coordinates and costs less per solve where the LM step's linear algebra dominates: on the CPU a 64-problem
    solve takes 6.9 ms instead of 23.5 (on an H100 the planner's time did not change measurably)."""

    def __init__(self, n: int, *, device, arm: str = "left"):
        self.n = n
        self.device = wp.get_device(device)
        self.arm = arm
        arm_joints = spec.JOINT_GROUPS[f"{arm}_arm"]
        chain = chain_joints(arm)
        with wp.ScopedDevice(self.device):
            whole, self.joints = _robot_builder()
            self.robot_coords = whole.joint_coord_count
            self.arm_coords = [self.joints.coord[j] for j in arm_joints]
            b, chain_index = _robot_builder(weld={j: 0.0 for j in spec.ALL_JOINT_NAMES if j not in chain})
            order = sorted(chain, key=lambda j: chain_index.coord[j])
            if [chain_index.coord[j] for j in order] != list(range(b.joint_coord_count)):
                raise ValueError(f"the {arm} arm's chain model has coordinates beside its joints {chain}")
            self._chain = np.array([self.joints.coord[j] for j in order])
            """Whole-robot coordinate of each chain-model coordinate."""
            self._link = chain_index.body[spec.END_EFFECTOR_LINK[arm]]
            self._bodies = b.body_count
            self._model = b.finalize(device=self.device)
            self._mask = np.zeros(self._model.joint_dof_count, dtype=bool)
            self._mask[[chain_index.dof[j] for j in arm_joints]] = True
            self._solvers: dict[int, tuple] = {}
            fk = newton.ModelBuilder()
            newton.solvers.SolverMuJoCo.register_custom_attributes(fk)
            fk.replicate(b, n)
            self._fk_model = fk.finalize(device=self.device)
            self._fk_state = self._fk_model.state()

    def _solver(self, k: int) -> tuple:
        """(position objective, rotation objective, IK solver, coordinate buffer) for ``k`` problems, built on
        first use (every size shares the compiled kernels: the problem count is a launch dimension)."""
        if k not in self._solvers:
            with wp.ScopedDevice(self.device):
                pos = ik.IKObjectivePosition(
                    link_index=self._link,
                    link_offset=wp.vec3(*spec.TCP_OFFSET_POS),
                    target_positions=wp.zeros(k, dtype=wp.vec3),
                )
                rot = ik.IKObjectiveRotation(
                    link_index=self._link,
                    link_offset_rotation=wp.quat(*spec.TCP_OFFSET_QUAT),
                    target_rotations=wp.array(np.tile(spec.TOP_DOWN_TCP_QUAT, (k, 1)), dtype=wp.vec4),
                )
                limits = ik.IKObjectiveJointLimit(
                    joint_limit_lower=self._model.joint_limit_lower,
                    joint_limit_upper=self._model.joint_limit_upper,
                    weight=10.0,
                )
                solver = ik.IKSolver(
                    model=self._model,
                    n_problems=k,
                    objectives=[pos, rot, limits],
                    lambda_initial=0.1,
                    jacobian_mode=ik.IKJacobianType.ANALYTIC,
                    joint_dof_mask=wp.array(self._mask, dtype=wp.bool),
                )
                self._solvers[k] = _Solve(pos, rot, solver, k, len(self._chain))
        return self._solvers[k]

    def solve(self, q_seed: np.ndarray, pos: np.ndarray, quat: np.ndarray, *, iterations: int = 48) -> np.ndarray:
        """Arm IK for ``m <= n`` problems: ``q_seed`` (m, 34) robot coordinates (base / legs / other joints are
        kept), target TCP ``pos`` (m, 3) and ``quat`` (m, 4) xyzw. Returns the solved (m, 34) coordinates. Fewer
        problems than ``n`` are solved by a solver of the next power-of-two size (padded with copies of the first
        problem), so the work follows the rows that need it."""
        q_seed, pos, quat = (np.asarray(a, dtype=np.float32) for a in (q_seed, pos, quat))
        m = q_seed.shape[0]
        if not 1 <= m <= self.n:
            raise ValueError(f"IK takes 1..{self.n} problems, got {m}")
        k = self.n if m == self.n else min(self.n, 1 << (m - 1).bit_length())
        if k > m:
            pad = lambda a: np.concatenate([a, np.repeat(a[:1], k - m, axis=0)])  # noqa: E731
            q_seed, pos, quat = pad(q_seed), pad(pos), pad(quat)
        with wp.ScopedDevice(self.device):
            chain = self._solver(k).run(q_seed[:, self._chain], pos, quat, iterations)[:m]
        out = q_seed[:m].copy()
        out[:, self._chain] = chain
        return out

    def tcp_poses(self, q: np.ndarray) -> np.ndarray:
        """TCP poses (m, 7) of ``m <= n`` robot coordinate rows ``q`` (m, 34). Only the ``m`` rows cross between
        host and device: the end-effector link of each, not every body of all ``n`` problems (4 MB a call at
        4096 rows, and a planner re-plan makes one call per solve)."""
        q = np.asarray(q, dtype=np.float32)
        m = q.shape[0]
        if not 1 <= m <= self.n:
            raise ValueError(f"FK takes 1..{self.n} coordinate rows, got {m}")
        chain = np.ascontiguousarray(q[:, self._chain])
        wp.to_torch(self._fk_state.joint_q)[: chain.size].copy_(torch.from_numpy(chain.reshape(-1)))
        newton.eval_fk(self._fk_model, self._fk_state.joint_q, self._fk_state.joint_qd, self._fk_state)
        body_q = wp.to_torch(self._fk_state.body_q).view(self.n, self._bodies, 7)
        link = body_q[:m, self._link].cpu().numpy().astype(np.float64)
        tcp_rot = np.tile(np.asarray(spec.TCP_OFFSET_QUAT, dtype=np.float64), (m, 1))
        pos = link[:, :3] + quat_rotate(link[:, 3:7], np.asarray(spec.TCP_OFFSET_POS, dtype=np.float64))
        return np.concatenate([pos, quat_mul(link[:, 3:7], tcp_rot)], axis=1)
