"""The solver's joint space beside the env's, when a task welds its idle joints (``PhysicsCfg.weld_idle_joints``).

The solver then steps a model with fewer coordinates (``SceneLayout.solver_model``) than the full robot that the
env's kernels, observations, agents and datasets see. The env's full-layout ``state`` stays the one truth: before
each solver step its coordinates, velocities and the drive's targets are copied into the solver's (welded ones
have no place there), after it the solver's coordinates and velocities are copied back, so a welded joint keeps
its posture and zero velocity. Body poses and twists are the same arrays in both states (welding keeps every
body in place), so the cameras, the TCP and forward kinematics of a reset need no copy.
"""

from __future__ import annotations

import newton
import numpy as np
import warp as wp

from .scene import SceneLayout


@wp.kernel
def full_to_solver(src: wp.array(dtype=float), index: wp.array(dtype=int), src_per_world: int,
                   dst_per_world: int, dst: wp.array(dtype=float)):
    """``dst`` (solver layout) from ``src`` (full layout) for every entry that is not welded (``index[i] >= 0``)."""
    w, i = wp.tid()
    j = index[i]
    if j >= 0:
        dst[w * dst_per_world + j] = src[w * src_per_world + i]


@wp.kernel
def solver_to_full(src: wp.array(dtype=float), index: wp.array(dtype=int), src_per_world: int,
                   dst_per_world: int, dst: wp.array(dtype=float)):
    """``dst`` (full layout) from ``src`` (solver layout); welded entries of ``dst`` are left as they are."""
    w, i = wp.tid()
    j = index[i]
    if j >= 0:
        dst[w * dst_per_world + i] = src[w * src_per_world + j]


class SolverJointSpace:
    """The solver model's state and drive, and the copies between them and the env's full-layout ones."""

    def __init__(self, layout: SceneLayout, state: newton.State, num_envs: int):
        self.model: newton.Model = layout.solver_model
        self.num_envs = num_envs
        self.state = self.model.state()
        """The solver's state: its own coordinates and velocities, the env state's body arrays."""
        self.state.body_q, self.state.body_qd = state.body_q, state.body_qd
        self.drive = self.model.control()
        """The targets the solver tracks, in its layout (copied from the env's drive before every step)."""
        self._coord = wp.array(layout.solver_coord, dtype=int)
        self._dof = wp.array(layout.solver_dof, dtype=int)
        self._full = (layout.coords_per_world, layout.dofs_per_world)
        self._solver = (self.model.joint_coord_count // num_envs, self.model.joint_dof_count // num_envs)
        self._target_per_coord = self.drive.joint_target_q.shape[0] == self.model.joint_coord_count

    def _copy(self, kernel, src: wp.array, dst: wp.array, per_dof: bool, to_solver: bool) -> None:
        index, full, solver = (self._dof, self._full[1], self._solver[1]) if per_dof else \
            (self._coord, self._full[0], self._solver[0])
        src_w, dst_w = (full, solver) if to_solver else (solver, full)
        wp.launch(kernel, dim=(self.num_envs, index.shape[0]), inputs=[src, index, src_w, dst_w], outputs=[dst])

    def push(self, state: newton.State, drive: newton.Control) -> None:
        """The env's coordinates, velocities and drive targets into the solver's."""
        self._copy(full_to_solver, state.joint_q, self.state.joint_q, False, True)
        self._copy(full_to_solver, state.joint_qd, self.state.joint_qd, True, True)
        self._copy(full_to_solver, drive.joint_target_q, self.drive.joint_target_q, not self._target_per_coord, True)
        self._copy(full_to_solver, drive.joint_target_qd, self.drive.joint_target_qd, True, True)

    def pull(self, state: newton.State) -> None:
        """The solver's coordinates and velocities back into the env's (welded ones keep their values)."""
        self._copy(solver_to_full, self.state.joint_q, state.joint_q, False, False)
        self._copy(solver_to_full, self.state.joint_qd, state.joint_qd, True, False)


def check_welded_reset(task_id: str, layout: SceneLayout, reset, welded_at) -> None:
    """Raise a one-line ``ValueError`` when a reset put a welded joint (``layout.welded``) anywhere but where the
    solver welded it. ``reset``: (rows, len(layout.welded)) their coordinates after the reset; ``welded_at``: one
    world's coordinates the solver model was welded at (``with_welded_solver``'s ``reset_q``)."""
    names = list(layout.welded)
    got = np.asarray(reset.cpu() if hasattr(reset, "cpu") else reset, dtype=np.float32).reshape(-1, len(names))
    want = np.asarray([welded_at[layout.joints.coord[n]] for n in names], dtype=np.float32)
    moved = np.abs(got - want).max(axis=0) > 1e-5
    if moved.any():
        j = int(np.argmax(moved))
        raise ValueError(f"{task_id}: the reset moves welded joint {names[j]!r} (welded at {want[j]:.4g}, reset to "
                         f"{got[:, j].tolist()}); drive it with an action term or declare "
                         "PhysicsCfg(weld_idle_joints=False)")
