"""The env's named parts: what ``NewtonEnv`` reaches beyond the gymnasium-like calls, grouped by concern.

``env.sim`` (``EnvSim``): Newton's objects, the solver's joint space, the captured step and its parts alone.
``env.task`` (``EnvTask``): the task's observation layout, signals, termination reasons, entities, phases, the
``TaskContext`` the fused kernels read and the kernels themselves. ``env.sensors`` (``EnvSensors``): the cameras and
their image terms. ``env.joints`` (``EnvJoints``): the robot on this scene (``BoundRobot``), its action map on the
device, joints by name and a scene placed by hand. ``env.buffers`` (``EnvBuffers``): the step's buffers as zero-copy
torch views, and the Warp arrays behind them. Each part is built by the env and only read by its users.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import newton
import numpy as np
import torch
import warp as wp

from ..robots.bound import BoundRobot
from .buffers import Entity, StepBuffers
from .cameras import Cameras, ImageViews
from .checks import row_mask
from .drive import Actuation, SolverJointSpace
from .launches import StepLaunches


class EnvSim:
    """The physics and the step's parts (for tools, timing and inspection).

    ``model``, ``state``, ``control`` and ``solver`` are Newton's own objects (also ``env.model`` ...); ``drive`` is
    the ``Control`` the solver tracks (``control``'s targets, velocity-limited joints' setpoints rate-limited);
    ``joint_space`` the solver's own joint space when the task welds its idle joints (``envs.drive``), else
    ``None``; ``layout`` the scene's layout (``envs.scene``: joints, bodies, entities per world, welded joints)."""

    def __init__(
        self,
        *,
        model,
        state,
        control,
        drive,
        solver,
        layout,
        joint_space: SolverJointSpace | None,
        launches: StepLaunches,
        cameras: Cameras,
        device,
    ):
        self.model, self.state, self.control, self.drive, self.solver = model, state, control, drive, solver
        self.layout = layout
        self.joint_space = joint_space
        self.step_graph = None
        """The captured step (a Warp graph; ``wp.capture_launch(env.sim.step_graph)`` steps
        ``env.buffers.actions`` as they are, unchecked), ``None`` when built with ``capture=False``."""
        self._launches, self._cameras, self._device = launches, cameras, device

    def capture_step(self) -> None:
        """Record the whole step as one Warp graph into ``step_graph`` (the env does it when built and reseeded)."""
        with wp.ScopedDevice(self._device):
            self.step_graph = self._launches.capture()

    def launch_step(self) -> None:
        """One step of the actions already in ``env.buffers.actions``, unchecked (the captured graph, else the same
        launches eagerly); ``env.step`` is this after its input check."""
        if self.step_graph is not None:
            wp.capture_launch(self.step_graph)
        else:
            with wp.ScopedDevice(self._device):
                self._launches.step()
        self._cameras.stale = True

    def apply_actions(self) -> None:
        """The step's first part alone: ``env.buffers.actions`` into the ``control`` targets (the action map)."""
        with wp.ScopedDevice(self._device):
            self._launches.apply_actions()

    def substep(self) -> None:
        """One physics substep alone: the base twist and drive setpoints, then ``solver.step`` by ``cfg.sim_dt``."""
        with wp.ScopedDevice(self._device):
            self._launches.substep()

    def simulate(self) -> None:
        """The step's physics alone: ``cfg.decimation`` substeps, no actions applied, no task, reset or
        observation. Inside a ``wp.ScopedCapture`` it records just them (``newton_lab.bench``'s bare solver)."""
        with wp.ScopedDevice(self._device):
            self._launches.simulate()

    def observe(self) -> None:
        """Recompute ``obs``, ``info["signals"]``, ``tcp_pose`` and ``entity_poses`` from the current state (after
        the state was written by hand, e.g. a replayed frame)."""
        with wp.ScopedDevice(self._device):
            self._launches.observe()
        self._cameras.stale = True

    @property
    def physics_exchange(self) -> str:
        """How the step's physics exchanges the state with MuJoCo-Warp: ``"control_step"`` (pushed before the
        first substep, pulled after the last: ``envs.mujoco_substeps``) or ``"substep"`` (Newton's
        ``SolverMuJoCo.step`` around every substep: ``PhysicsCfg.sync_every_substep``)."""
        return "substep" if self._launches.control_step_physics is None else "control_step"

    @property
    def bodies_per_world(self) -> int:
        """Bodies of one world (robot and entities); world ``w``'s bodies start at ``w * bodies_per_world``."""
        return self.layout.bodies_per_world

    def contact_count(self) -> int:
        """Active MuJoCo contacts summed over all worlds after the last step (host sync)."""
        return int(self.solver.mjw_data.nacon.numpy()[0])

    def constraint_rows(self) -> int:
        """Largest number of MuJoCo constraint rows in any world after the last step (host sync)."""
        return int(self.solver.mjw_data.nefc.numpy().max())


@dataclass(frozen=True, kw_only=True)
class EnvTask:
    """The task as the env runs it (read-only)."""

    obs_terms: dict[str, slice]
    """Observation name -> its columns of ``env.obs``."""
    obs_dim: int
    """Columns of ``env.obs``."""
    signal_names: tuple[str, ...]
    """Subtask signals, the columns of ``info["signals"]``."""
    termination_reasons: tuple[str, ...]
    """``info["termination_reason"]`` indexes this."""
    entities: dict[str, Entity]
    """The scene's entities by name (``Entity``: slot in ``entity_poses``, body, first coordinate)."""
    scenario: Any
    """The scenario the rows reset to (``envs.scenario``), ``None`` without one."""
    phases: tuple
    """A coherent task's phases (``cfg.phases``), empty for a component task."""
    randomize: bool
    """The reset randomisation is on (seeded per row and episode by ``env.seed``)."""
    context: Any
    """The ``TaskContext`` struct every fused kernel reads (state arrays, robot indices, phase, per-row counters
    such as ``episode_step``); the step writes it."""
    kernels: Any
    """The task's fused kernels (``envs.launches.TaskKernels``: ``task``, ``observe``, ``signals``, ``reset``)."""


@dataclass(frozen=True, kw_only=True)
class EnvSensors:
    """The rendered cameras (``envs.cameras``) and their image terms."""

    cameras: Cameras
    """The renderer: specs, intrinsics, poses, segmentation names, ``render(force, eager)``."""
    camera_specs: dict
    """The cameras the env renders, by name (resolution, data kinds, mount)."""
    image_terms: dict
    """Image observations by name (``front_head_rgb``, ...): camera, data, per-row shape, dtype."""
    images: ImageViews
    """Image observations as torch views, rendered on first read after a step or reset (a step whose images are not
    read renders nothing)."""

    def render(self) -> dict[str, torch.Tensor]:
        """Render the cameras for the current state (if not done since the last step / reset); returns the image
        views by name (empty without cameras)."""
        return self.cameras.render()


@dataclass(frozen=True, kw_only=True)
class EnvBuffers:
    """The step's buffers as zero-copy torch views of its Warp arrays (overwritten by the next step)."""

    obs: torch.Tensor
    reward: torch.Tensor
    terminated: torch.Tensor
    truncated: torch.Tensor
    info: dict[str, Any]
    actions: torch.Tensor
    """(num_envs, action_dim) the actions the next step applies (``env.step`` copies its input here)."""
    final_obs: torch.Tensor
    """(num_envs, obs_dim) observation of the state the last step reached, before an automatic reset replaced it:
    the last observation of a finished episode (rows whose ``info["done"]`` is set); ``obs`` in the other rows."""
    terminal_joint_q: torch.Tensor
    """(num_envs, coords_per_world) coordinates of each row's last finished episode, taken just before its
    automatic reset (valid for rows whose ``info["done"]`` is set)."""
    episode_count: torch.Tensor
    """(num_envs,) episodes started per row (changes when a row resets; agents key per-row state on it; zeroing it
    makes the rows' next resets draw what a fresh env's do)."""
    tcp_pose: torch.Tensor
    """(num_envs, 7) TCP pose of the controlled arm, world frame."""
    entity_poses: torch.Tensor
    """(num_envs, num_entities, 7) entity poses, world frame."""
    arrays: StepBuffers
    """The Warp arrays themselves (``envs.buffers.StepBuffers``)."""

    @classmethod
    def views(cls, buf: StepBuffers, ctx, *, obs_dim: int, entities: int, signals: int, command_dim: int):
        t = wp.to_torch
        return cls(
            obs=t(buf.obs)[:, :obs_dim],
            reward=t(buf.reward),
            terminated=t(buf.terminated),
            truncated=t(buf.truncated),
            info=buf.info(ctx, signals=signals, command_dim=command_dim),
            actions=t(buf.actions),
            final_obs=t(buf.final_obs)[:, :obs_dim],
            terminal_joint_q=t(buf.terminal_q),
            episode_count=t(buf.episode_count),
            tcp_pose=t(buf.tcp_pose),
            entity_poses=t(buf.entity_poses)[:, :entities],
            arrays=buf,
        )


class EnvJoints:
    """The robot on this scene: its binding, the action map on the device, joints by name, a scene placed by hand."""

    def __init__(self, *, binding: BoundRobot, actuation: Actuation, sim: EnvSim, num_envs: int, torch_device):
        self.binding = binding
        """``robots.bound.BoundRobot``: the robot half of the task context, the action map, the drive limits."""
        self.actuation = actuation
        """The action map and drive limits on the device (``envs.drive.Actuation``)."""
        self._sim, self._num_envs, self._torch_device = sim, num_envs, torch_device

    @property
    def action_terms(self) -> dict[str, slice]:
        """The action's columns of each action term, by term name."""
        return self.binding.actions.terms

    @property
    def robot_coords(self) -> int:
        """Coordinates of the robot at the start of each world's row of ``joint_q`` (its entities follow)."""
        return self._sim.layout.robot_coords

    def absolute_column_ranges(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) float64 (action_dim,): each absolute-target column's joint range from the model [rad | m],
        -inf .. inf for the other columns."""
        amap, dof = self.binding.actions, self._sim.layout.joints.dof
        model = self._sim.layout.model
        lower, upper = model.joint_limit_lower.numpy(), model.joint_limit_upper.numpy()
        low, high = np.full(amap.dim, -np.inf), np.full(amap.dim, np.inf)
        for c, (name, kind) in enumerate(zip(amap.joint_names, amap.kinds)):
            if kind == "absolute":
                low[c], high[c] = lower[dof[name]], upper[dof[name]]
        return low, high

    def coords(self, names) -> list[int]:
        """World-local coordinate of each named robot joint (its column in a row of ``joint_q`` /
        ``joint_target_q``, viewed as (num_envs, coords_per_world)); raises a one-line ``KeyError`` for a joint
        the robot lacks."""
        coord = self._sim.layout.joints.coord
        missing = [n for n in names if n not in coord]
        if missing:
            raise KeyError(f"no robot joint {missing[0]!r}; the robot's joints are {list(coord)}")
        return [coord[n] for n in names]

    def positions(self, names) -> torch.Tensor:
        """(num_envs, len(names)) current positions of the named robot joints [rad | m]."""
        q = wp.to_torch(self._sim.state.joint_q).view(self._num_envs, -1)
        return q[:, self.coords(names)]

    def dofs(self, names) -> list[int]:
        """World-local velocity index of each named robot joint (its column in a row of ``joint_qd``); raises a
        one-line ``KeyError`` for a joint the robot lacks."""
        self.coords(names)  # the one-line error for an unknown name
        return [self._sim.layout.joints.dof[n] for n in names]

    def velocities(self, names) -> torch.Tensor:
        """(num_envs, len(names)) current velocities of the named robot joints [rad/s | m/s]."""
        qd = wp.to_torch(self._sim.state.joint_qd).view(self._num_envs, -1)
        return qd[:, self.dofs(names)]

    def set_positions(self, names, values, env_ids=None) -> None:
        """Place the named robot joints of rows ``env_ids`` (all when ``None``) at ``values`` [rad | m]
        ((len(names),) or (rows, len(names))): positions (velocities zeroed), targets and drive setpoints together,
        then forward kinematics and ``observe``. Writing ``state.joint_q`` and ``control.joint_target_q`` alone
        leaves a rate-limited setpoint (the grippers') behind for up to 0.6 s: the drive pulls the joint back."""
        sim = self._sim
        coords = self.coords(names)
        rows = torch.as_tensor(row_mask(env_ids, self._num_envs), device=self._torch_device).nonzero().flatten()
        vals = torch.as_tensor(values, dtype=torch.float32, device=self._torch_device)
        if vals.shape not in ((len(coords),), (len(rows), len(coords))):
            raise ValueError(
                f"values has shape {tuple(vals.shape)}; pass ({len(coords)},) or ({len(rows)}, "
                f"{len(coords)}): one value per named joint (per row)"
            )
        dofs = [sim.layout.joints.dof[n] for n in names]
        self.actuation.place(sim.state, rows, coords, dofs, vals.expand(len(rows), len(coords)))
        with wp.ScopedDevice(sim.model.device):
            newton.eval_fk(sim.model, sim.state.joint_q, sim.state.joint_qd, sim.state)
        sim.observe()

    def sync_drive(self, env_ids=None) -> None:
        """The drive setpoints of rows ``env_ids`` (all when ``None``) jump to ``control``'s targets: call it after
        writing ``control.joint_target_q`` by hand (``set_positions`` does it itself)."""
        with wp.ScopedDevice(self._sim.model.device):
            self.actuation.sync(wp.array(row_mask(env_ids, self._num_envs), dtype=bool))
