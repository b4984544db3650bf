"""The solver's joint space beside the env's, when a task welds its idle joints (``PhysicsCfg.weld_idle_joints``).

The solver then steps a model with fewer coordinates and bodies (``SceneLayout.solver_model``: the welded links
merged into their parents) than the full robot that the env's kernels, observations, agents, cameras and datasets
see. The env's full-layout ``state`` stays the one truth: before each solver step its coordinates, velocities and
the drive's targets are copied into the solver's (welded ones have no place there); after it the solver's
coordinates and velocities are copied back, so a welded joint keeps its reset value and zero velocity. Once the
substeps of a control step are done, the full model's forward kinematics gives every body's pose and twist.
"""

from __future__ import annotations

import newton
import numpy as np
import warp as wp

from .scene import SceneLayout


@wp.kernel
def full_to_solver(
    q: wp.array(dtype=float),
    qd: wp.array(dtype=float),
    target_q: wp.array(dtype=float),
    target_qd: wp.array(dtype=float),
    coord: wp.array(dtype=int),
    dof: wp.array(dtype=int),
    full_coords: int,
    full_dofs: int,
    coords: int,
    dofs: int,
    solver_q: wp.array(dtype=float),
    solver_qd: wp.array(dtype=float),
    solver_target_q: wp.array(dtype=float),
    solver_target_qd: wp.array(dtype=float),
):
    """Row ``w``, entry ``i``: the env's coordinate / velocity / drive targets into the solver's, unless welded
    (``coord[i]`` / ``dof[i]`` < 0). Position targets follow the coordinates, velocity targets the DOFs."""
    w, i = wp.tid()
    if i < full_coords:
        j = coord[i]
        if j >= 0:
            solver_q[w * coords + j] = q[w * full_coords + i]
            solver_target_q[w * coords + j] = target_q[w * full_coords + i]
    if i < full_dofs:
        j = dof[i]
        if j >= 0:
            solver_qd[w * dofs + j] = qd[w * full_dofs + i]
            solver_target_qd[w * dofs + j] = target_qd[w * full_dofs + i]


@wp.kernel
def solver_to_full(
    solver_q: wp.array(dtype=float),
    solver_qd: wp.array(dtype=float),
    coord: wp.array(dtype=int),
    dof: wp.array(dtype=int),
    full_coords: int,
    full_dofs: int,
    coords: int,
    dofs: int,
    q: wp.array(dtype=float),
    qd: wp.array(dtype=float),
):
    """Row ``w``, entry ``i``: the solver's coordinate and velocity back into the env's; welded entries keep
    their values."""
    w, i = wp.tid()
    if i < full_coords:
        j = coord[i]
        if j >= 0:
            q[w * full_coords + i] = solver_q[w * coords + j]
    if i < full_dofs:
        j = dof[i]
        if j >= 0:
            qd[w * full_dofs + i] = solver_qd[w * dofs + j]


class SolverJointSpace:
    """The solver model's state and drive, and the copies between them and the env's full-layout ones."""

    def __init__(self, layout: SceneLayout, num_envs: int):
        self.model: newton.Model = layout.solver_model
        self.full_model: newton.Model = layout.model
        self.num_envs = num_envs
        self.state = self.model.state()
        """The solver's state, in its own layout (coordinates, velocities, its merged bodies)."""
        self.drive = self.model.control()
        """The targets the solver tracks, in its layout (copied from the env's drive before every step)."""
        self.solver_coord = np.asarray(layout.solver_coord, dtype=np.int64)
        """Per full-layout coordinate of a world: its coordinate in the solver's, or -1 where welded."""
        self._coord = wp.array(layout.solver_coord, dtype=int)
        self._dof = wp.array(layout.solver_dof, dtype=int)
        self._full = (layout.coords_per_world, layout.dofs_per_world)
        self._solver = (self.model.joint_coord_count // num_envs, self.model.joint_dof_count // num_envs)
        if self.drive.joint_target_q.shape[0] != self.model.joint_coord_count:
            raise RuntimeError(
                "Newton's position targets are no longer one per coordinate; envs.joint_space copies them by coordinate"
            )
        self._dims = (num_envs, max(self._full))

    def push(self, state: newton.State, drive: newton.Control) -> None:
        """The env's coordinates, velocities and drive targets into the solver's (one launch)."""
        d = self.drive
        wp.launch(
            full_to_solver,
            dim=self._dims,
            inputs=[
                state.joint_q,
                state.joint_qd,
                drive.joint_target_q,
                drive.joint_target_qd,
                self._coord,
                self._dof,
                *self._full,
                *self._solver,
            ],
            outputs=[self.state.joint_q, self.state.joint_qd, d.joint_target_q, d.joint_target_qd],
        )

    def pull(self, state: newton.State) -> None:
        """The solver's coordinates and velocities back into the env's (one launch; welded ones keep theirs)."""
        wp.launch(
            solver_to_full,
            dim=self._dims,
            inputs=[self.state.joint_q, self.state.joint_qd, self._coord, self._dof, *self._full, *self._solver],
            outputs=[state.joint_q, state.joint_qd],
        )

    def forward_kinematics(self, state: newton.State) -> None:
        """The env's body poses and twists from its coordinates, on the full model (after ``pull``)."""
        newton.eval_fk(self.full_model, state.joint_q, state.joint_qd, state)


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
        raise ValueError(
            f"{task_id}: the reset moves welded joint {names[j]!r} (welded at {want[j]:.4g}, reset to "
            f"{got[:, j].tolist()}); drive it with an action term or declare "
            "PhysicsCfg(weld_idle_joints=False)"
        )
