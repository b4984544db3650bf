"""The batched env: transparent over Newton, one captured graph per env step.

One step, as data (all on the env's device; the captured step allocates nothing and never syncs to the host):
actions -> ``apply_actions`` (the robot binding's action map, ``actuation``) -> (base twist, drive setpoints,
``solver.step``) x decimation -> fused task kernel -> masked reset of finished rows (+ seeded randomisation)
-> forward kinematics of reset rows -> fused observation kernel (the launches: ``envs.launches``). ``step``
checks its input first, which reads the actions' finiteness on the host.

The public surface beyond ``step`` / ``reset``, for tools and tests: the step's parts (``step_graph``,
``launch_step``, ``apply_actions``, ``substep``, ``simulate``, ``observe``), its arrays (``buffers``,
``task_context``, ``kernels``, ``actuation``, ``physics_exchange``) and joint / entity views by name (``joint_coords``,
``joint_positions``, ``entities``, ``robot_coords``, ``bodies_per_world``), and a scene placed by hand
(``set_joint_positions``, ``sync_drive``). Code outside ``envs/`` uses only these
and the public attributes; ``tests/test_architecture.py`` checks it touches nothing private.
"""

from __future__ import annotations

from typing import Any

import newton
import torch
import warp as wp

from ..robots.binding import RobotBinding
from ..robots.registry import robot_binding
from ..robots.bound import BoundRobot
from ..task_api.cfg import TaskCfg
from ..task_api.cfg import ACTION_DIM, ARM_JOINTS, ROBOT_COORDS
from . import rollout
from .actuation import Actuation
from .buffers import Entity, StepBuffers, build_context, entity_table, reset_coordinates
from .cameras import Cameras, ImageViews, resolve_cameras
from .checks import check_actions, check_seed, row_mask
from .joint_space import SolverJointSpace, check_welded_reset
from .launches import StepLaunches
from .scene import build_scene, with_welded_solver
from .terms import build_task_kernels, observation_layout

__all__ = ["Entity", "NewtonEnv"]


class NewtonEnv:
    """A batch of ``num_envs`` worlds of one robot (``robot``, the binding the task's config names) running one task.

    Transparent: ``model``, ``state``, ``control`` and ``solver`` are Newton's own objects; the step
    writes into them in place. ``control`` holds the targets the actions command; the solver tracks ``drive``
    (the same targets, velocity-limited joints' setpoints rate-limited, see ``actuation``). ``step`` returns
    torch tensors that share memory with Warp arrays.
    """

    def __init__(
        self,
        cfg: TaskCfg,
        *,
        num_envs: int = 1,
        device: str | None = None,
        seed: int | None = None,
        randomize: bool = False,
        capture: bool = True,
        cameras: bool | dict | str | None = None,
    ):
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if not getattr(cfg, "task_id", None):
            raise ValueError("this TaskCfg names no task: TaskSpec.cfg() neither names it nor resolves its generic "
                             "terms; build the env with make_env(task_id), or from TaskSpec.make_cfg(options)")
        self.cfg = cfg
        self.task_id = cfg.task_id
        self.num_envs = num_envs
        self.device = wp.get_device(device)
        self.torch_device = torch.device(wp.device_to_torch(self.device))
        self.seed = 0 if seed is None else check_seed(seed)
        self.randomize = bool(randomize)
        self.robot: RobotBinding = robot_binding(cfg.robot)
        """The robot's facts (``robots.binding.RobotBinding``): joint groups, arms, TCP, gripper range, cameras, its
        kinematics; agents, Mimic and the viewers read the robot only through it."""
        self.camera_specs = resolve_cameras(cfg, cameras, robot=self.robot)  # a bad request fails before the build

        with wp.ScopedDevice(self.device):
            layout = build_scene(cfg, num_envs, str(self.device), self.robot)
            self.scenario, default_q, default_target_q = reset_coordinates(cfg, layout)
            self.layout = with_welded_solver(cfg, layout, default_q, num_envs, str(self.device))
            self.model = self.layout.model
            self.state = self.model.state()
            self.control = self.model.control()
            self.joint_space = SolverJointSpace(self.layout, num_envs) if self.layout.welded else None
            """The solver's own joint space when the task welds its idle joints (``envs.joint_space``), else
            ``None``: the solver steps ``model`` itself."""
            self.solver = newton.solvers.SolverMuJoCo(self.layout.solver_model, **cfg.physics.solver_options())
            # mujoco_warp prints a line from inside its kernels whenever a world overflows a buffer or the line
            # search hits its cap; the per-world bitmask (solver_overflows) is reported by the loops instead
            self.solver.mjw_model.opt.warn_overflow = 0
            self._build_actions()
            self._build_buffers(default_q, default_target_q)
            self._build_launches()
            self._build_cameras(capture)
            self.reset()
            if self.joint_space is not None:
                check_welded_reset(self.task_id, self.layout, self.joint_positions(list(self.layout.welded)),
                                   default_q)
            self._graph = self._launches.capture() if capture else None

    # ------------------------------------------------------------------ construction
    def _build_actions(self) -> None:
        self.binding = BoundRobot.from_layout(self.robot, self.layout, actions=self.cfg.actions, arm=self.cfg.arm)
        """The robot on this scene (``robots.bound.BoundRobot``): robot half of the task context, the action map,
        the drive limits."""
        action_map = self.binding.actions
        self.action_joint_names = action_map.joint_names
        self.action_terms = action_map.terms
        self.action_dim = action_map.dim
        self._actuation = Actuation(self.binding, self.cfg, self.layout, self.control, self.num_envs)
        self.drive = self._actuation.drive
        """The Newton ``Control`` the solver tracks (``control``'s targets, velocity limits applied)."""

    def _build_observation_layout(self) -> None:
        lay, cfg = self.layout, self.cfg
        self.obs_terms = observation_layout(cfg, {ACTION_DIM: self.action_dim, ROBOT_COORDS: lay.robot_coords,
                                                  ARM_JOINTS: len(self.binding.context.arm_coords)})
        self.obs_dim = max((s.stop for s in self.obs_terms.values()), default=0)

    def _build_buffers(self, default_q, default_target_q) -> None:
        n, lay, cfg = self.num_envs, self.layout, self.cfg
        self._build_observation_layout()
        self.entities = entity_table(lay)
        """The scene's entities by name (``Entity``: slot in ``entity_poses``, body, first coordinate)."""
        self.signal_names = tuple(cfg.signals)
        self.termination_reasons = cfg.termination_reasons
        self._buf = buf = StepBuffers.allocate(
            num_envs=n, action_dim=self.action_dim, obs_dim=self.obs_dim, signals=len(self.signal_names),
            entities=len(lay.entity_names), articulations=self.model.articulation_count,
            coords_per_world=lay.coords_per_world)
        self._default_q = wp.array(default_q, dtype=float)
        self._default_target_q = wp.array(default_target_q, dtype=float)
        self._ctx = build_context(cfg=cfg, layout=lay, binding=self.binding, state=self.state, control=self.control,
                                  actions=buf.actions, num_envs=n)
        self._build_views()

    def _build_views(self) -> None:
        """The public torch views of the step buffers (they share memory with the Warp arrays)."""
        buf, n_ent = self._buf, len(self.layout.entity_names)
        t = wp.to_torch
        self.obs = t(buf.obs)[:, : self.obs_dim]
        self.reward = t(buf.reward)
        self.terminated = t(buf.terminated)
        self.truncated = t(buf.truncated)
        self.actions = t(buf.actions)
        self.info: dict[str, Any] = buf.info(self._ctx, signals=len(self.signal_names),
                                             command_dim=self.cfg.command_dim)
        self.tcp_pose = t(buf.tcp_pose)
        """(num_envs, 7) TCP pose of the controlled arm, world frame, updated every step."""
        self.entity_poses = t(buf.entity_poses)[:, :n_ent]
        """(num_envs, num_entities, 7) entity poses, world frame, updated every step."""
        self.episode_count = t(buf.episode_count)
        """(num_envs,) episodes started per row (changes when a row resets; agents key per-row state on it;
        zeroing it makes the rows' next resets draw what a fresh env's do)."""
        self.terminal_joint_q = t(buf.terminal_q)
        """(num_envs, coords_per_world) coordinates of each row's last finished episode, taken just before
        its automatic reset (valid for rows whose ``info["done"]`` is set)."""
        self.final_obs = t(buf.final_obs)[:, : self.obs_dim]
        """(num_envs, obs_dim) observation of the state the last step reached, before an automatic reset
        replaced it: the last observation of a finished episode (rows whose ``info["done"]`` is set); equal to
        ``obs`` in the other rows."""

    def _build_cameras(self, capture: bool) -> None:
        lay = self.layout
        self.cameras = Cameras(self.camera_specs, model=self.model, state=self.state,
                               num_envs=self.num_envs, bodies_per_world=lay.bodies_per_world,
                               entity_names=lay.entity_names, capture=capture, randomize=self.randomize,
                               seed=lambda: self.seed, episode=self._buf.episode_count,
                               keep_hue=[e.name for e in self.cfg.entities if e.keep_hue], robot=self.robot)
        """The rendered cameras (``envs.cameras``): specs, intrinsics, poses, segmentation names."""
        self.image_terms = self.cameras.terms
        """Image observations by name (``front_head_rgb``, ...): camera, data, per-row shape, dtype."""
        self.images = ImageViews(self.cameras)
        """Image observations as torch views, rendered on first read after a step or reset (a step whose images
        are not read renders nothing)."""

    def render(self) -> dict[str, torch.Tensor]:
        """Render the cameras for the current state (if not done since the last step / reset); returns the image
        views by name (empty without cameras)."""
        return self.cameras.render()

    def _build_launches(self) -> None:
        self._kernels = build_task_kernels(self.cfg, self.obs_terms)
        self._launches = StepLaunches(
            cfg=self.cfg, model=self.model, state=self.state, solver=self.solver, drive=self.drive,
            actuation=self._actuation, ctx=self._ctx, buffers=self._buf, kernels=self._kernels,
            default_q=self._default_q, default_target_q=self._default_target_q, seed=lambda: self.seed,
            randomize=lambda: self.randomize, joint_space=self.joint_space)

    # ------------------------------------------------------------------ the step
    def step(self, actions: torch.Tensor):
        """Advance every row one control step.

        Args:
            actions: (num_envs, action_dim) float32 tensor on the env's device; columns follow
                ``action_joint_names``, each of the kind ``binding.actions.kinds`` names (absolute or relative
                joint targets [rad], wheel speeds [rad/s], gripper targets from ``robot.gripper_open`` to
                ``robot.gripper_closed``: the G1's 0 .. 1.2).

        Returns:
            ``(obs, reward, terminated, truncated, info)`` as torch views of the env's Warp buffers
            (overwritten by the next step). Rows that finished were reset in the same step: ``obs`` is
            their new episode's first observation, and ``info`` holds the finished episode's
            ``success``, ``termination_reason``, ``episode_length`` and ``step_signals`` (subtask
            signals of the state the step reached; ``info["signals"]`` belong to ``obs``). A row whose
            physics diverged (non-finite or beyond ``cfg.divergence_bounds``) ends with reason ``diverged``.
        """
        self.actions.copy_(self.check_actions(actions).detach())  # a policy's graph never reaches the env's buffer
        self.launch_step()
        return self.obs, self.reward, self.terminated, self.truncated, self.info

    def reset(self, env_ids=None):
        """Reset the given rows (all when ``None``); other rows are untouched. Returns ``(obs, info)``."""
        self._buf.reset_mask.assign(row_mask(env_ids, self.num_envs))
        with wp.ScopedDevice(self.device):
            self._launches.reset(self._buf.reset_mask)
        self.cameras.stale = True
        return self.obs, self.info

    def reseed(self, seed: int):
        """Restart the reset randomisation from ``seed`` and reset every row: the rows then start the episodes a
        new env built with ``seed`` starts (episode counters back to 0, the captured step re-recorded with the
        new seed). Returns ``(obs, info)``."""
        self.seed = check_seed(seed)
        if self._graph is not None:
            with wp.ScopedDevice(self.device):
                self._graph = self._launches.capture()
        self.episode_count.zero_()
        return self.reset()

    # ------------------------------------------------------------------ the step's parts (timing, inspection)
    @property
    def step_graph(self):
        """The captured step (a Warp graph; ``wp.capture_launch(env.step_graph)`` steps ``env.actions`` as they
        are, unchecked), ``None`` when built with ``capture=False`` or where Warp cannot capture."""
        return self._graph

    def launch_step(self) -> None:
        """One step of the actions already in ``env.actions``, unchecked (the captured graph, else the same
        launches eagerly); ``step`` is this after its input check."""
        if self._graph is not None:
            wp.capture_launch(self._graph)
        else:
            with wp.ScopedDevice(self.device):
                self._launches.step()
        self.cameras.stale = True

    def apply_actions(self) -> None:
        """The step's first part alone: ``env.actions`` into the ``control`` targets (the binding's action map)."""
        with wp.ScopedDevice(self.device):
            self._launches.apply_actions()

    def substep(self) -> None:
        """One physics substep alone: the base twist and drive setpoints (``actuation``), then ``solver.step`` by
        ``cfg.sim_dt``."""
        with wp.ScopedDevice(self.device):
            self._launches.substep()

    def simulate(self) -> None:
        """The step's physics alone: ``cfg.decimation`` substeps, no actions applied, no task, reset or
        observation. Inside a ``wp.ScopedCapture`` it records just them (``newton_lab.bench``'s bare solver)."""
        with wp.ScopedDevice(self.device):
            self._launches.simulate()

    def observe(self) -> None:
        """Recompute ``obs``, ``info["signals"]``, ``tcp_pose`` and ``entity_poses`` from the current state (after
        the state was written by hand, e.g. a replayed frame)."""
        with wp.ScopedDevice(self.device):
            self._launches.observe()
        self.cameras.stale = True

    @property
    def buffers(self) -> StepBuffers:
        """The step's Warp arrays (``envs.buffers.StepBuffers``); ``obs``, ``reward``, ``info`` ... are their torch
        views. Read them; the step writes them."""
        return self._buf

    @property
    def task_context(self):
        """The ``TaskContext`` struct every fused kernel reads (state arrays, robot indices, phase, per-row
        counters such as ``episode_step``); for inspection: the step writes it."""
        return self._ctx

    @property
    def kernels(self):
        """The task's fused kernels (``envs.terms.TaskKernels``: ``task``, ``observe``, ``signals``, ``reset``);
        ``envs.launches`` launches them."""
        return self._kernels

    @property
    def actuation(self) -> Actuation:
        """The action map and drive limits on the device (``envs.actuation.Actuation``)."""
        return self._actuation

    @property
    def physics_exchange(self) -> str:
        """How the step's physics exchanges the state with MuJoCo-Warp: ``"control_step"`` (pushed before the
        first substep, pulled after the last: ``envs.mujoco_substeps``) or ``"substep"`` (Newton's
        ``SolverMuJoCo.step`` around every substep: ``PhysicsCfg.sync_every_substep``)."""
        return "substep" if self._launches.control_step_physics is None else "control_step"

    @property
    def robot_coords(self) -> int:
        """Coordinates of the robot at the start of each world's row of ``joint_q`` (its entities follow)."""
        return self.layout.robot_coords

    @property
    def bodies_per_world(self) -> int:
        """Bodies of one world (robot and entities); world ``w``'s bodies start at ``w * bodies_per_world``."""
        return self.layout.bodies_per_world

    def joint_coords(self, names) -> list[int]:
        """World-local coordinate of each named robot joint (its column in a row of ``joint_q`` /
        ``joint_target_q``, viewed as (num_envs, coords_per_world)); raises a one-line ``KeyError`` for a joint
        the robot lacks."""
        coord = self.layout.joints.coord
        missing = [n for n in names if n not in coord]
        if missing:
            raise KeyError(f"no robot joint {missing[0]!r}; the robot's joints are {list(coord)}")
        return [coord[n] for n in names]

    # ------------------------------------------------------------------ a scene placed by hand
    def set_joint_positions(self, names, values, env_ids=None) -> None:
        """Place the named robot joints of rows ``env_ids`` (all when ``None``) at ``values`` [rad | m]
        ((len(names),) or (rows, len(names))): positions (velocities zeroed), targets and drive setpoints together,
        then forward kinematics and ``observe``. Writing ``state.joint_q`` and ``control.joint_target_q`` alone
        leaves a rate-limited setpoint (the grippers') behind for up to 0.6 s: the drive pulls the joint back."""
        coords = self.joint_coords(names)
        rows = torch.as_tensor(row_mask(env_ids, self.num_envs), device=self.torch_device).nonzero().flatten()
        vals = torch.as_tensor(values, dtype=torch.float32, device=self.torch_device)
        if vals.shape not in ((len(coords),), (len(rows), len(coords))):
            raise ValueError(f"values has shape {tuple(vals.shape)}; pass ({len(coords)},) or ({len(rows)}, "
                             f"{len(coords)}): one value per named joint (per row)")
        dofs = [self.layout.joints.dof[n] for n in names]
        self._actuation.place(self.state, rows, coords, dofs, vals.expand(len(rows), len(coords)))
        with wp.ScopedDevice(self.device):
            newton.eval_fk(self.model, self.state.joint_q, self.state.joint_qd, self.state)
        self.observe()

    def sync_drive(self, env_ids=None) -> None:
        """The drive setpoints of rows ``env_ids`` (all when ``None``) jump to ``control``'s targets: call it after
        writing ``control.joint_target_q`` by hand (``set_joint_positions`` does it itself)."""
        with wp.ScopedDevice(self.device):
            self._actuation.sync(wp.array(row_mask(env_ids, self.num_envs), dtype=bool))

    # ------------------------------------------------------------------ input checks
    def check_actions(self, actions) -> torch.Tensor:
        """Validate an action tensor; raises a one-line ``ValueError`` naming the problem and the fix."""
        return check_actions(actions, num_envs=self.num_envs, action_dim=self.action_dim, device=self.torch_device,
                             columns=self.action_joint_names)

    # ------------------------------------------------------------------ conveniences
    def contact_count(self) -> int:
        """Active MuJoCo contacts summed over all worlds after the last step (host sync)."""
        return int(self.solver.mjw_data.nacon.numpy()[0])

    def constraint_rows(self) -> int:
        """Largest number of MuJoCo constraint rows in any world after the last step (host sync)."""
        return int(self.solver.mjw_data.nefc.numpy().max())

    def joint_positions(self, names) -> torch.Tensor:
        """(num_envs, len(names)) current positions of the named robot joints [rad | m]."""
        q = wp.to_torch(self.state.joint_q).view(self.num_envs, -1)
        return q[:, self.joint_coords(names)]

    def current_action(self) -> torch.Tensor:
        """An action that holds every commanded joint at its current target (absolute / binary columns: the
        target; relative and wheel-velocity columns: 0)."""
        return self._actuation.hold()

    def collect(self, *, agent, episodes: int, path, max_steps: int = 1000, progress: bool = True, **kwargs):
        """Run ``agent`` for ``episodes`` episodes and write them to ``path``; returns a ``DatasetRef``
        whose metadata is the run summary (see ``newton_lab.envs.rollout.collect``)."""
        return rollout.collect(self, agent=agent, episodes=episodes, path=path, max_steps=max_steps, progress=progress,
                       **kwargs)

    def evaluate(self, *, agent, episodes: int, max_steps: int = 1000, progress: bool = True, **kwargs):
        """Run ``agent`` for ``episodes`` episodes and report success rate and lengths (see ``rollout``)."""
        return rollout.evaluate(self, agent=agent, episodes=episodes, max_steps=max_steps, progress=progress, **kwargs)
