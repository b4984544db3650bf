"""The robot binding's action map and drive limits on the device, and the launches that use them.

Two Newton ``Control`` objects: ``control`` holds the targets the actions command (what agents read back and
hold), ``drive`` what the solver tracks. They share every array except the targets: each physics substep
``drive_setpoints`` copies the targets into the drive, except that a velocity-limited joint's setpoint moves
toward its target at no more than the limit the model declares (``joint_velocity_limit``, which SolverMuJoCo
does not apply itself), with that velocity as its drive's velocity target.
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
