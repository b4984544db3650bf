"""The batched env: transparent over Newton, one captured graph per env step.

One step, as data (all on the env's device; the captured step allocates nothing and never syncs to the host):
actions -> ``apply_actions`` (the robot binding's action map, ``actuation``) -> (base twist, drive setpoints,
``solver.step``) x decimation -> fused task kernel -> masked reset of finished rows (+ seeded randomisation)
-> forward kinematics of reset rows -> fused observation kernel (the launches: ``envs.launches``). ``step``
checks its input first, which reads the actions' finiteness on the host.

The env itself holds the gymnasium-like surface (``step``, ``reset``, ``reseed``, ``render``, the step's results,
``num_envs``, ``device``, ``action_dim``, ``action_joint_names``), Newton's own objects (``model``, ``state``,
``control``, ``solver``), the robot's facts (``robot``) and five named parts (``envs.parts``): ``sim`` (the physics
and the step's parts alone), ``task`` (observation layout, signals, entities, phases, context, kernels),
``sensors`` (cameras, images), ``joints`` (the robot on this scene: binding, actuation, joints by name, a scene
placed by hand) and ``buffers`` (every step buffer as a torch view). Code outside ``envs/`` uses only these;
``tests/test_architecture.py`` checks the count of names, the parts' names and that nothing private is touched.
"""

from __future__ import annotations

import newton
import torch
import warp as wp

from ..robots.binding import RobotBinding
from ..robots.bound import BoundRobot
from ..robots.registry import robot_binding
from ..task_api.cfg import ACTION_DIM, ARM_JOINTS, ROBOT_COORDS, TaskCfg
from ..task_api.terms import resolved_cfg
from . import rollout
from .buffers import Entity, StepBuffers, build_context, entity_table, reset_coordinates
from .cameras import Cameras, ImageViews, resolve_cameras
from .checks import check_actions, check_seed, row_mask
from .drive import Actuation, SolverJointSpace, check_welded_reset
from .launches import StepLaunches, build_task_kernels, observation_layout
from .parts import EnvBuffers, EnvJoints, EnvSensors, EnvSim, EnvTask
from .scene import build_scene, with_welded_solver

__all__ = ["Entity", "NewtonEnv"]


class NewtonEnv:
    """A batch of ``num_envs`` worlds of one robot (``robot``, the binding the task's config names) running one task.

    Transparent: ``model``, ``state``, ``control`` and ``solver`` are Newton's own objects; the step
    writes into them in place. ``control`` holds the targets the actions command; the solver tracks
    ``sim.drive`` (the same targets, velocity-limited joints' setpoints rate-limited, see ``joints.actuation``).
    ``step`` returns torch tensors that share memory with Warp arrays.
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
        cfg = resolved_cfg(cfg)
        self.cfg = cfg
        self.task_id = cfg.task_id
        self.num_envs = num_envs
        self.device = wp.get_device(device)
        self.torch_device = torch.device(wp.device_to_torch(self.device))
        self.seed = 0 if seed is None else check_seed(seed)
        self.robot: RobotBinding = robot_binding(cfg.robot)
        """The robot's facts (``robots.binding.RobotBinding``): joint groups, arms, TCP, gripper range, cameras, its
        kinematics; agents, Mimic and the viewers read the robot only through it."""
        camera_specs = resolve_cameras(cfg, cameras, robot=self.robot)  # a bad request fails before the build

        with wp.ScopedDevice(self.device):
            layout = build_scene(cfg, num_envs, str(self.device), self.robot)
            scenario, default_q, default_target_q = reset_coordinates(cfg, layout)
            layout = with_welded_solver(cfg, layout, default_q, num_envs, str(self.device))
            self.model = layout.model
            self.state = self.model.state()
            self.control = self.model.control()
            self.solver = newton.solvers.SolverMuJoCo(layout.solver_model, **cfg.physics.solver_options())
            # mujoco_warp prints a line from inside its kernels whenever a world overflows a buffer or the line
            # search hits its cap; the per-world bitmask (solver_overflows) is reported by the loops instead
            self.solver.mjw_model.opt.warn_overflow = 0
            self._build(layout, scenario, default_q, default_target_q, camera_specs, bool(randomize), capture)
            self.reset()
            if self.sim.joint_space is not None:
                check_welded_reset(self.task_id, layout, self.joints.positions(list(layout.welded)), default_q)
            if capture:
                self.sim.capture_step()

    # ------------------------------------------------------------------ construction
    def _build(
        self, layout, scenario, default_q, default_target_q, camera_specs, randomize: bool, capture: bool
    ) -> None:
        """The action map, the step buffers and task context, the kernels and launches, the cameras, and the named
        parts over them."""
        binding, actuation, buf, ctx, kernels = self._build_task(layout, scenario, randomize)
        cams = self._build_sensors(layout, camera_specs, buf, capture, randomize)
        self._build_sim(layout, binding, actuation, buf, ctx, kernels, cams, default_q, default_target_q, randomize)

    def _build_task(self, layout, scenario, randomize: bool):
        """The action map and actuation, the observation layout, the step buffers, the task context and kernels:
        ``self.buffers`` and ``self.task``."""
        cfg, n = self.cfg, self.num_envs
        binding = BoundRobot.from_layout(self.robot, layout, actions=cfg.actions, arm=cfg.arm)
        self.action_joint_names = binding.actions.joint_names
        """The action's columns: the joint each commands."""
        self.action_dim = binding.actions.dim
        actuation = Actuation(binding, cfg, layout, self.control, n)
        obs_terms = observation_layout(
            cfg,
            {
                ACTION_DIM: self.action_dim,
                ROBOT_COORDS: layout.robot_coords,
                ARM_JOINTS: len(binding.context.arm_coords),
            },
        )
        obs_dim = max((s.stop for s in obs_terms.values()), default=0)
        signal_names = tuple(cfg.signals)
        buf = StepBuffers.allocate(
            num_envs=n,
            action_dim=self.action_dim,
            obs_dim=obs_dim,
            signals=len(signal_names),
            entities=len(layout.entity_names),
            articulations=self.model.articulation_count,
            coords_per_world=layout.coords_per_world,
        )
        ctx = build_context(
            cfg=cfg,
            layout=layout,
            binding=binding,
            state=self.state,
            control=self.control,
            actions=buf.actions,
            num_envs=n,
        )
        kernels = build_task_kernels(cfg, obs_terms)
        self.buffers = EnvBuffers.views(
            buf,
            ctx,
            obs_dim=obs_dim,
            entities=len(layout.entity_names),
            signals=len(signal_names),
            command_dim=cfg.command_dim,
        )
        """The step's buffers as torch views (``envs.parts.EnvBuffers``); ``obs``, ``reward``, ``info`` ... are
        also on the env."""
        self.obs, self.reward, self.info = self.buffers.obs, self.buffers.reward, self.buffers.info
        self.terminated, self.truncated = self.buffers.terminated, self.buffers.truncated
        self.task = EnvTask(
            obs_terms=obs_terms,
            obs_dim=obs_dim,
            signal_names=signal_names,
            termination_reasons=cfg.termination_reasons,
            entities=entity_table(layout),
            scenario=scenario,
            phases=tuple(cfg.phases),
            randomize=randomize,
            context=ctx,
            kernels=kernels,
        )
        """The task as the env runs it (``envs.parts.EnvTask``)."""
        return binding, actuation, buf, ctx, kernels

    def _build_sensors(self, layout, camera_specs, buf, capture: bool, randomize: bool):
        """The cameras and their image terms: ``self.sensors``."""
        cfg, n = self.cfg, self.num_envs
        cams = Cameras(
            camera_specs,
            model=self.model,
            state=self.state,
            num_envs=n,
            bodies_per_world=layout.bodies_per_world,
            entity_names=layout.entity_names,
            capture=capture,
            randomize=randomize,
            seed=lambda: self.seed,
            episode=buf.episode_count,
            keep_hue=[e.name for e in cfg.entities if e.keep_hue],
            hidden_groups=self.robot.hidden_link_groups({term.group for term in cfg.actions}),
            robot=self.robot,
        )
        self.sensors = EnvSensors(
            cameras=cams, camera_specs=camera_specs, image_terms=cams.terms, images=ImageViews(cams)
        )
        """The cameras and their image terms (``envs.parts.EnvSensors``)."""
        return cams

    def _build_sim(
        self, layout, binding, actuation, buf, ctx, kernels, cams, default_q, default_target_q, randomize: bool
    ) -> None:
        """The step's launches, the physics part and the joints: ``self.sim``, ``self.joints``."""
        cfg, n = self.cfg, self.num_envs
        launches = StepLaunches(
            cfg=cfg,
            model=self.model,
            state=self.state,
            solver=self.solver,
            drive=actuation.drive,
            actuation=actuation,
            ctx=ctx,
            buffers=buf,
            kernels=kernels,
            default_q=wp.array(default_q, dtype=float),
            default_target_q=wp.array(default_target_q, dtype=float),
            seed=lambda: self.seed,
            randomize=lambda: randomize,
            joint_space=SolverJointSpace(layout, n) if layout.welded else None,
        )
        self.sim = EnvSim(
            model=self.model,
            state=self.state,
            control=self.control,
            drive=actuation.drive,
            solver=self.solver,
            layout=layout,
            joint_space=launches.joint_space,
            launches=launches,
            cameras=cams,
            device=self.device,
        )
        """The physics and the step's parts alone (``envs.parts.EnvSim``)."""
        self.joints = EnvJoints(
            binding=binding, actuation=actuation, sim=self.sim, num_envs=n, torch_device=self.torch_device
        )
        """The robot on this scene (``envs.parts.EnvJoints``)."""
        self._launches = launches

    def render(self) -> dict[str, torch.Tensor]:
        """Render the cameras for the current state (if not done since the last step / reset); returns the image
        views by name (empty without cameras)."""
        return self.sensors.render()

    # ------------------------------------------------------------------ the step
    def step(self, actions: torch.Tensor, *, check_finite: bool = True):
        """Advance every row one control step.

        Args:
            actions: (num_envs, action_dim) float32 tensor on the env's device; columns follow
                ``action_joint_names``, each of the kind ``joints.binding.actions.kinds`` names (absolute or
                relative joint targets [rad], wheel speeds [rad/s], gripper targets from ``robot.gripper_open`` to
                ``robot.gripper_closed``: the G1's 0 .. 1.2).
            check_finite: refuse NaN or inf actions, which reads them on the host (the step then waits for the
                device). ``False`` leaves that to the caller: PPO's vec env checks on the device and reads the
                result once an iteration.

        Returns:
            ``(obs, reward, terminated, truncated, info)`` as torch views of the env's Warp buffers
            (overwritten by the next step). Rows that finished were reset in the same step: ``obs`` is
            their new episode's first observation, and ``info`` holds the finished episode's
            ``success``, ``termination_reason``, ``episode_length`` and ``step_signals`` (subtask
            signals of the state the step reached; ``info["signals"]`` belong to ``obs``). A row whose
            physics diverged (non-finite or beyond ``cfg.divergence_bounds``) ends with reason ``diverged``.
        """
        checked = check_actions(
            actions,
            num_envs=self.num_envs,
            action_dim=self.action_dim,
            device=self.torch_device,
            columns=self.action_joint_names,
            finite=check_finite,
        )
        self.buffers.actions.copy_(checked.detach())  # a policy's graph never reaches the env's buffer
        self.sim.launch_step()
        return self.obs, self.reward, self.terminated, self.truncated, self.info

    def reset(self, env_ids=None):
        """Reset the given rows (all when ``None``); other rows are untouched. Returns ``(obs, info)``."""
        mask = self.buffers.arrays.reset_mask
        mask.assign(row_mask(env_ids, self.num_envs))
        with wp.ScopedDevice(self.device):
            self._launches.reset(mask)
        self.sensors.cameras.stale = True
        return self.obs, self.info

    def reseed(self, seed: int):
        """Restart the reset randomisation from ``seed`` and reset every row: the rows then start the episodes a
        new env built with ``seed`` starts (episode counters back to 0, the captured step re-recorded with the
        new seed). Returns ``(obs, info)``."""
        self.seed = check_seed(seed)
        if self.sim.step_graph is not None:
            self.sim.capture_step()
        self.buffers.episode_count.zero_()
        return self.reset()

    # ------------------------------------------------------------------ conveniences
    def current_action(self) -> torch.Tensor:
        """An action that holds every commanded joint at its current target (absolute / binary columns: the
        target; relative and wheel-velocity columns: 0)."""
        return self.joints.actuation.hold()

    def collect(self, *, agent, episodes: int, path, max_steps: int = 1000, progress: bool = True, **kwargs):
        """Run ``agent`` for ``episodes`` episodes and write them to ``path``; returns a ``DatasetRef``
        whose metadata is the run summary (see ``newton_lab.envs.rollout.collect``)."""
        return rollout.collect(
            self, agent=agent, episodes=episodes, path=path, max_steps=max_steps, progress=progress, **kwargs
        )

    def evaluate(self, *, agent, episodes: int, max_steps: int = 1000, progress: bool = True, **kwargs):
        """Run ``agent`` for ``episodes`` episodes and report success rate and lengths (see ``rollout``)."""
        return rollout.evaluate(self, agent=agent, episodes=episodes, max_steps=max_steps, progress=progress, **kwargs)
