"""The batched G1 env: transparent over Newton, one captured graph per env step.

One step, as data (all on the env's device, nothing allocated, no host sync):
actions -> ``apply_actions`` (the robot binding's action map, ``actuation``) -> (base twist, drive setpoints,
``solver.step``) x decimation -> fused task kernel -> masked reset of finished rows (+ seeded randomisation)
-> forward kinematics of reset rows -> fused observation kernel.
"""

from __future__ import annotations

from typing import Any

import newton
import numpy as np
import torch
import warp as wp

from ..kernels import fuse
from ..kernels.context import record_poses
from ..robots.g1.binding import G1Binding
from ..task_api.cfg import TaskCfg
from ..task_api.cfg import ACTION_DIM, ARM_JOINTS, ROBOT_COORDS
from . import rollout
from .actuation import Actuation
from .buffers import Entity, build_context, entity_table, reset_coordinates
from .cameras import Cameras, ImageViews, resolve_cameras
from .scene import build_scene
from .terms import build_task_kernels, observation_layout

__all__ = ["Entity", "NewtonEnv"]


class NewtonEnv:
    """A batch of ``num_envs`` G1 worlds running one task.

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
        self.cfg = cfg
        self.task_id = cfg.task_id
        self.num_envs = num_envs
        self.device = wp.get_device(device)
        self.torch_device = torch.device(wp.device_to_torch(self.device))
        self.seed = 0 if seed is None else int(seed)
        self.randomize = bool(randomize)
        self.camera_specs = resolve_cameras(cfg, cameras)  # a bad camera request fails before the build

        with wp.ScopedDevice(self.device):
            self.layout = build_scene(cfg, num_envs, str(self.device))
            self.model = self.layout.model
            self.state = self.model.state()
            self.control = self.model.control()
            self.solver = newton.solvers.SolverMuJoCo(
                self.model,
                use_mujoco_cpu=False,
                solver="newton",
                integrator="implicitfast",
                cone="elliptic",
                iterations=20,
                ls_iterations=10,
                impratio=10,
                nconmax=cfg.contacts_per_world,
                njmax=cfg.constraints_per_world,
            )
            # mujoco_warp prints a line from inside its kernels whenever a world overflows a buffer or the line
            # search hits its cap; the per-world bitmask (solver_overflows) is reported by the loops instead
            self.solver.mjw_model.opt.warn_overflow = 0
            self._build_actions()
            self._build_buffers()
            self._build_kernels()
            self._build_cameras(capture)
            self.reset()
            self._graph = self._capture() if capture else None

    # ------------------------------------------------------------------ construction
    def _build_actions(self) -> None:
        self.binding = G1Binding.from_layout(self.layout, actions=self.cfg.actions, arm=self.cfg.arm)
        """The G1 on this scene: robot half of the task context, the action map, the drive limits."""
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

    def _build_buffers(self) -> None:
        n, lay, cfg = self.num_envs, self.layout, self.cfg
        self._build_observation_layout()
        n_ent = len(lay.entity_names)
        self.entities = entity_table(lay)
        self.signal_names = tuple(cfg.signals)
        self.termination_reasons = cfg.termination_reasons

        z = wp.zeros
        self._actions = z((n, self.action_dim), dtype=float)
        self._obs = z((n, max(self.obs_dim, 1)), dtype=float)
        self._reward = z(n, dtype=float)
        self._terminated = z(n, dtype=bool)
        self._truncated = z(n, dtype=bool)
        self._done = z(n, dtype=bool)
        self._success = z(n, dtype=bool)
        self._success_latched = z(n, dtype=bool)
        self._reason = z(n, dtype=int)
        self._episode_length = z(n, dtype=int)
        self._signals = z((n, max(len(self.signal_names), 1)), dtype=float)
        self._step_signals = z((n, max(len(self.signal_names), 1)), dtype=float)
        self._episode_count = z(n, dtype=int)
        self._reset_mask = z(n, dtype=bool)
        self._art_mask = z(self.model.articulation_count, dtype=bool)
        self._tcp_pose = z((n, 7), dtype=float)
        self._entity_poses = z((n, max(n_ent, 1), 7), dtype=float)
        self.scenario, default_q, default_target_q = reset_coordinates(cfg, lay)
        self._default_q = wp.array(default_q, dtype=float)
        self._default_target_q = wp.array(default_target_q, dtype=float)
        self._terminal_q = z((n, lay.coords_per_world), dtype=float)
        self._final_obs = z((n, max(self.obs_dim, 1)), dtype=float)
        self._ctx = build_context(cfg=cfg, layout=lay, binding=self.binding, state=self.state, control=self.control,
                                  actions=self._actions, num_envs=n)
        self._build_views()

    def _build_views(self) -> None:
        """The public torch views of the step buffers (they share memory with the Warp arrays)."""
        cfg, ctx, n_ent = self.cfg, self._ctx, len(self.layout.entity_names)
        t = wp.to_torch
        self.obs = t(self._obs)[:, : self.obs_dim]
        self.reward = t(self._reward)
        self.terminated = t(self._terminated)
        self.truncated = t(self._truncated)
        self.actions = t(self._actions)
        self.info: dict[str, Any] = {
            "success": t(self._success),
            "success_latched": t(self._success_latched),
            "done": t(self._done),
            "termination_reason": t(self._reason),
            "episode_length": t(self._episode_length),
            "phase": t(ctx.phase),
            "signals": t(self._signals)[:, : len(self.signal_names)],
            # the same signals on the state the step reached, before an automatic reset replaced it
            "step_signals": t(self._step_signals)[:, : len(self.signal_names)],
            "command": t(ctx.command)[:, : cfg.command_dim],
        }
        self.tcp_pose = t(self._tcp_pose)
        """(num_envs, 7) TCP pose of the controlled arm, world frame, updated every step."""
        self.entity_poses = t(self._entity_poses)[:, :n_ent]
        """(num_envs, num_entities, 7) entity poses, world frame, updated every step."""
        self.episode_count = t(self._episode_count)
        """(num_envs,) episodes started per row (changes when a row resets; agents key per-row state on it)."""
        self.terminal_joint_q = t(self._terminal_q)
        """(num_envs, coords_per_world) coordinates of each row's last finished episode, taken just before
        its automatic reset (valid for rows whose ``info["done"]`` is set)."""
        self.final_obs = t(self._final_obs)[:, : self.obs_dim]
        """(num_envs, obs_dim) observation of the state the last step reached, before an automatic reset
        replaced it: the last observation of a finished episode (rows whose ``info["done"]`` is set); equal to
        ``obs`` in the other rows."""

    def _build_cameras(self, capture: bool) -> None:
        lay = self.layout
        self.cameras = Cameras(self.camera_specs, model=self.model, state=self.state,
                               num_envs=self.num_envs, bodies_per_world=lay.bodies_per_world,
                               entity_names=lay.entity_names, capture=capture, randomize=self.randomize,
                               seed=lambda: self.seed, episode=self._episode_count,
                               keep_hue=[e.name for e in self.cfg.entities if e.keep_hue])
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

    def _build_kernels(self) -> None:
        kernels = build_task_kernels(self.cfg, self.obs_terms)
        self._task_kernel, self._obs_kernel = kernels.task, kernels.observe
        self._signal_kernel, self._reset_kernel = kernels.signals, kernels.reset

    def _capture(self):
        """Record the whole step as one graph (CUDA graph on GPU, Warp's CPU graph on the CPU)."""
        try:
            with wp.ScopedCapture(device=self.device) as cap:
                self._step_body()
        except Exception:  # pragma: no cover - depends on the Warp build; eager stepping stays correct
            return None
        return cap.graph

    # ------------------------------------------------------------------ the step
    def _apply_actions(self) -> None:
        self._actuation.apply(self._actions, self._ctx.phase)

    def _simulate(self) -> None:
        for _ in range(self.cfg.decimation):
            # per substep: the world-frame base twist follows the turning base, limited setpoints advance
            self._actuation.substep(self._actions, self._ctx.phase, self.state.joint_q)
            self.solver.step(self.state, self.state, self.drive, None, self.cfg.sim_dt)

    def _evaluate_task(self) -> None:
        wp.launch(
            self._task_kernel,
            dim=self.num_envs,
            inputs=[self._ctx, self.cfg.max_episode_steps, wp.vec3(*self.cfg.divergence_bounds)],
            outputs=[
                self._reward,
                self._terminated,
                self._truncated,
                self._done,
                self._success,
                self._success_latched,
                self._reason,
                self._episode_length,
            ],
        )

    def _reset_rows(self, mask: wp.array) -> None:
        wp.launch(
            self._reset_kernel,
            dim=self.num_envs,
            inputs=[
                self._ctx,
                mask,
                self._default_q,
                self._default_target_q,
                self.seed,
                int(self.randomize),
                self._episode_count,
                self._success_latched,
            ],
        )
        self._actuation.sync(mask)  # the reset rows' drive setpoints jump to their reset targets
        wp.launch(
            fuse.world_to_articulation_mask,
            dim=self.model.articulation_count,
            inputs=[mask, self.model.articulation_world, self._art_mask],
        )
        newton.eval_fk(self.model, self.state.joint_q, self.state.joint_qd, self.state, mask=self._art_mask)
        data = self.solver.mjw_data  # the reset worlds' solver history (NaN after a divergence) is cleared
        wp.launch(fuse.clear_solver_warmstart, dim=data.qacc_warmstart.shape,
                  inputs=[mask, data.qacc_warmstart, data.qacc, data.qvel])

    def _write_signals(self, out: wp.array2d) -> None:
        if self._signal_kernel is not None:
            wp.launch(self._signal_kernel, dim=self.num_envs, inputs=[self._ctx, out])

    def _observe(self) -> None:
        wp.launch(self._obs_kernel, dim=self.num_envs, inputs=[self._ctx, self._obs])
        self._write_signals(self._signals)
        wp.launch(record_poses, dim=self.num_envs, inputs=[self._ctx, self._tcp_pose, self._entity_poses])

    def _step_body(self) -> None:
        self._apply_actions()
        self._simulate()
        self._evaluate_task()
        self._write_signals(self._step_signals)
        wp.launch(self._obs_kernel, dim=self.num_envs, inputs=[self._ctx, self._final_obs])
        wp.launch(fuse.keep_terminal_coords, dim=self._terminal_q.shape,
                  inputs=[self._done, self.state.joint_q, self._terminal_q])
        self._reset_rows(self._done)
        self._observe()

    def step(self, actions: torch.Tensor):
        """Advance every row one control step.

        Args:
            actions: (num_envs, action_dim) float32 tensor on the env's device; columns follow
                ``action_joint_names``, each of the kind ``binding.actions.kinds`` names (absolute or relative
                joint targets [rad], wheel speeds [rad/s], gripper 0 open .. 1.2 closed).

        Returns:
            ``(obs, reward, terminated, truncated, info)`` as torch views of the env's Warp buffers
            (overwritten by the next step). Rows that finished were reset in the same step: ``obs`` is
            their new episode's first observation, and ``info`` holds the finished episode's
            ``success``, ``termination_reason``, ``episode_length`` and ``step_signals`` (subtask
            signals of the state the step reached; ``info["signals"]`` belong to ``obs``). A row whose
            physics diverged (non-finite or beyond ``cfg.divergence_bounds``) ends with reason ``diverged``.
        """
        self.actions.copy_(self.check_actions(actions))
        if self._graph is not None:
            wp.capture_launch(self._graph)
        else:
            with wp.ScopedDevice(self.device):
                self._step_body()
        self.cameras.stale = True
        return self.obs, self.reward, self.terminated, self.truncated, self.info

    def reset(self, env_ids=None):
        """Reset the given rows (all when ``None``); other rows are untouched. Returns ``(obs, info)``."""
        mask = np.zeros(self.num_envs, dtype=bool)
        if env_ids is None:
            mask[:] = True
        else:
            given = torch.as_tensor(env_ids).cpu()
            if given.numel() and (given.dtype.is_floating_point or given.dtype.is_complex or given.dtype == torch.bool):
                raise ValueError(f"env_ids must be integer row indices, got dtype {given.dtype}; pass e.g. "
                                 f"torch.nonzero(mask).flatten() for a boolean mask")
            ids = given.numpy().astype(np.int64).reshape(-1)
            if ids.size and (ids.min() < 0 or ids.max() >= self.num_envs):
                raise ValueError(f"env_ids must lie in [0, {self.num_envs}), got {ids.tolist()}")
            mask[ids] = True
        self._reset_mask.assign(mask)
        with wp.ScopedDevice(self.device):
            wp.launch(fuse.keep_terminal_coords, dim=self._terminal_q.shape,
                      inputs=[self._reset_mask, self.state.joint_q, self._terminal_q])
            self._reset_rows(self._reset_mask)
            self._observe()
        self.cameras.stale = True
        return self.obs, self.info

    def reseed(self, seed: int):
        """Restart the reset randomisation from ``seed`` and reset every row: the rows then start the episodes a
        new env built with ``seed`` starts (episode counters back to 0, the captured step re-recorded with the
        new seed). Returns ``(obs, info)``."""
        if not isinstance(seed, int) or isinstance(seed, bool):
            raise ValueError(f"seed must be an int, got {seed!r}")
        self.seed = seed
        if self._graph is not None:
            with wp.ScopedDevice(self.device):
                self._graph = self._capture()
        self.episode_count.zero_()
        return self.reset()

    # ------------------------------------------------------------------ input checks
    def check_actions(self, actions) -> torch.Tensor:
        """Validate an action tensor; raises a one-line ``ValueError`` naming the problem and the fix."""
        if not isinstance(actions, torch.Tensor):
            raise ValueError(
                f"actions must be a torch.Tensor, got {type(actions).__name__}; "
                f"use torch.as_tensor(actions, dtype=torch.float32, device='{self.torch_device}')"
            )
        expected = (self.num_envs, self.action_dim)
        if tuple(actions.shape) != expected:
            raise ValueError(
                f"actions must have shape (num_envs, action_dim) = {expected}, got {tuple(actions.shape)}; "
                f"columns are {list(self.action_joint_names)}"
            )
        if actions.dtype != torch.float32:
            raise ValueError(f"actions must be torch.float32, got {actions.dtype}; convert with actions.float()")
        if actions.device != self.torch_device:
            raise ValueError(
                f"actions are on {actions.device} but the env runs on {self.torch_device}; "
                f"move them with actions.to('{self.torch_device}')"
            )
        finite = torch.isfinite(actions)
        if not bool(finite.all()):
            rows = torch.nonzero(~finite.all(dim=1)).flatten().tolist()
            raise ValueError(f"actions contain NaN or inf in rows {rows}; check the agent's output before stepping")
        return actions

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
        return q[:, [self.layout.joints.coord[n] for n in names]]

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
