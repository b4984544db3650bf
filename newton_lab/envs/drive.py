"""The robot's drive: how the actions reach the solver's joints, and the solver's own, smaller joint space when a
task welds its idle joints.

``Actuation``: the robot binding's action map and drive limits on the device, and the launches that use them. Two
Newton ``Control`` objects: ``control`` holds the targets the actions command (what agents read back and hold),
``drive`` what the solver tracks. They share every array except the targets: each physics substep
``drive_setpoints`` copies the targets into the drive, except that a velocity-limited joint's setpoint moves toward
its target at no more than the limit the model declares (``joint_velocity_limit``, which SolverMuJoCo does not apply
itself), with that velocity as its drive's velocity target.

``SolverJointSpace``: with ``PhysicsCfg.weld_idle_joints`` the solver steps a model with fewer coordinates and bodies
(``SceneLayout.solver_model``: the welded links merged into their parents) than the full robot that the env's
kernels, observations, agents, cameras and datasets see. The env's full-layout ``state`` stays the one truth: before
each solver step its coordinates, velocities and the drive's targets are copied into the solver's (welded ones have
no place there); after it the solver's coordinates and velocities are copied back, so a welded joint keeps its reset
value and zero velocity. Once the substeps of a control step are done, the full model's forward kinematics gives
every body's pose and twist.
"""

from __future__ import annotations

import copy

import newton
import numpy as np
import torch
import warp as wp

from ..kernels.actions import KIND_CODE, apply_actions, drive_base, drive_setpoints, sync_setpoints
from ..robots.bound import BoundRobot
from ..task_api.cfg import TaskCfg
from .scene import SceneLayout


def _farray(values: np.ndarray) -> wp.array:
    return wp.array(np.asarray(values, dtype=np.float32), dtype=float)


class Actuation:
    """Per control step: actions -> targets (``apply``). Per physics substep: wheel columns -> planar base
    velocity, targets -> drive setpoints (``substep``). After a masked reset: setpoints jump to the reset
    targets (``sync``); joints placed by hand move target and setpoint together (``place``). Warp arrays live on the
    current device."""

    def __init__(self, binding: BoundRobot, cfg: TaskCfg, layout: SceneLayout, control: newton.Control, num_envs: int):
        amap, limits = binding.actions, binding.limits
        self.num_envs, self.layout, self.control, self.sim_dt = num_envs, layout, control, cfg.sim_dt
        self.dim, self.wheel_col = amap.dim, amap.wheel_col
        self.map = amap
        owned, base_free = amap.ownership(cfg.phases, cfg.fixed_base)
        self.owned = wp.array(owned, dtype=bool)
        self.base_free = wp.array(base_free, dtype=bool)
        self.kind = wp.array([KIND_CODE[k] for k in amap.kinds], dtype=int)
        self.index = wp.array(amap.index, dtype=int)
        self.scale, self.low, self.high = _farray(amap.scale), _farray(amap.low), _farray(amap.high)
        self.target_low, self.target_high = _farray(amap.target_low), _farray(amap.target_high)
        self.max_step = _farray(limits.max_rate * cfg.sim_dt)
        self.coord_dof = wp.array(limits.coord_dof, dtype=int)
        self.dof_limited = wp.array(limits.dof_limited, dtype=bool)
        self.lin_gain, self.yaw_gain = binding.robot.wheel_gains
        base_x = binding.robot.base_planar_joints[0]
        self.base_coord = layout.joints.coord[base_x]
        self.base_dof = layout.joints.dof[base_x]
        self.drive = copy.copy(control)
        """What the solver tracks: ``control``'s arrays, but its own position / velocity targets."""
        self.drive.joint_target_q = wp.clone(control.joint_target_q)
        self.drive.joint_target_qd = wp.clone(control.joint_target_qd)
        rows = (num_envs, layout.coords_per_world)
        self._target_rows = control.joint_target_q.reshape(rows)
        self._setpoint_rows = self.drive.joint_target_q.reshape(rows)

    def apply(self, actions: wp.array2d, phase: wp.array) -> None:
        """Write a control step's actions into ``control``'s targets (columns the row's phase owns)."""
        lay = self.layout
        wp.launch(
            apply_actions,
            dim=(self.num_envs, self.dim),
            inputs=[
                actions,
                self.kind,
                self.index,
                self.scale,
                self.low,
                self.high,
                self.target_low,
                self.target_high,
                self.owned,
                phase,
                lay.coords_per_world,
                lay.dofs_per_world,
            ],
            outputs=[self.control.joint_target_q, self.control.joint_target_qd],
        )

    def substep(
        self, actions: wp.array2d, phase: wp.array, joint_q: wp.array, yaw: tuple[wp.array, int, int] | None = None
    ) -> None:
        """Before one physics substep: the wheel columns' base twist (rotated by the current yaw) into
        ``control``, then ``control``'s targets into the ``drive``. The yaw is read from the env's ``joint_q``,
        or from ``yaw`` = (flat array, stride per world, offset) where the coordinates live elsewhere between
        substeps (MuJoCo-Warp's ``qpos``: ``envs.mujoco_substeps``)."""
        lay = self.layout
        if self.wheel_col >= 0:
            yaw_q, stride, offset = yaw or (joint_q, lay.coords_per_world, self.base_coord + 2)
            wp.launch(
                drive_base,
                dim=self.num_envs,
                inputs=[
                    actions,
                    self.wheel_col,
                    self.scale,
                    self.low,
                    self.high,
                    self.owned,
                    self.base_free,
                    phase,
                    self.lin_gain,
                    self.yaw_gain,
                    self.base_dof,
                    lay.dofs_per_world,
                    yaw_q,
                    stride,
                    offset,
                ],
                outputs=[self.control.joint_target_qd],
            )
        wp.launch(
            drive_setpoints,
            dim=(self.num_envs, max(lay.coords_per_world, lay.dofs_per_world)),
            inputs=[
                self.control.joint_target_q,
                self.control.joint_target_qd,
                self.max_step,
                self.coord_dof,
                self.dof_limited,
                self.sim_dt,
                lay.coords_per_world,
                lay.dofs_per_world,
            ],
            outputs=[self.drive.joint_target_q, self.drive.joint_target_qd],
        )

    def sync(self, mask: wp.array) -> None:
        """Setpoints of the masked rows jump to their (just reset) targets."""
        wp.launch(
            sync_setpoints, dim=self._target_rows.shape, inputs=[mask, self._target_rows], outputs=[self._setpoint_rows]
        )

    def place(
        self, state: newton.State, rows: torch.Tensor, coords: list[int], dofs: list[int], values: torch.Tensor
    ) -> None:
        """Positions (velocities zeroed), targets and setpoints of ``rows`` x ``coords`` set to ``values`` (rows,
        coords) at once: the drive holds them there from the next substep."""
        n, at = self.num_envs, rows[:, None]
        cols, dof_cols = (torch.as_tensor(c, device=rows.device) for c in (coords, dofs))
        for array in (state.joint_q, self.control.joint_target_q, self.drive.joint_target_q):
            wp.to_torch(array).view(n, -1)[at, cols] = values
        wp.to_torch(state.joint_qd).view(n, -1)[at, dof_cols] = 0.0

    def hold(self) -> torch.Tensor:
        """An action that holds every column at its current target (see ``ActionMap.hold``)."""
        targets = wp.to_torch(self.control.joint_target_q).view(self.num_envs, -1)
        return self.map.hold(targets)


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
                "Newton's position targets are no longer one per coordinate; envs.drive copies them by coordinate"
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
