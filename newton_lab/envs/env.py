"""The batched G1 env: transparent over Newton, one captured graph per env step.

One step, as data (all on the env's device, nothing allocated, no host sync):
actions -> ``apply_actions`` -> ``solver.step`` x decimation -> fused task kernel -> masked reset of
finished rows (+ seeded randomisation) -> forward kinematics of reset rows -> fused observation kernel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import newton
import numpy as np
import torch
import warp as wp

from ..kernels import fuse
from ..kernels.actions import TARGET_POSITION, TARGET_VELOCITY, apply_actions, drive_base
from ..kernels.context import TaskContext, record_poses
from ..robots.g1 import spec
from ..robots.g1.packers import wheel_gains
from ..task_api.cfg import TaskCfg
from ..task_api.cfg import ACTION_DIM, ARM_JOINTS, ROBOT_COORDS
from . import rollout
from .scenario import load_scenario
from .scene import build_scene
from .terms import build_task_kernels, observation_layout


@dataclass(frozen=True)
class Entity:
    """A named rigid object of the scene; ``slot`` indexes ``env.entity_poses``."""

    name: str
    slot: int
    body: int
    """World-local body index, -1 for a static collider."""
    dynamic: bool


class NewtonEnv:
    """A batch of ``num_envs`` G1 worlds running one task.

    Transparent: ``model``, ``state``, ``control`` and ``solver`` are Newton's own objects; the step
    writes into them in place. ``step`` returns torch tensors that share memory with Warp arrays.
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
            self._build_actions()
            self._build_buffers()
            self._build_kernels()
            self.reset()
            self._graph = self._capture() if capture else None

    # ------------------------------------------------------------------ construction
    def _build_actions(self) -> None:
        joints = self.layout.joints
        names, kind, index, low, high, self.action_terms = [], [], [], [], [], {}
        for term in self.cfg.actions:
            group = spec.JOINT_GROUPS[term.group]
            start = len(names)
            for j in group:
                names.append(j)
                if term.type == "velocity":
                    kind.append(TARGET_VELOCITY)
                    index.append(joints.dof[j])
                else:
                    kind.append(TARGET_POSITION)
                    index.append(joints.coord[j])
                lo, hi = term.clip if term.clip else (-np.inf, np.inf)
                if term.type == "binary":
                    lo, hi = spec.GRIPPER_OPEN, spec.GRIPPER_CLOSED
                low.append(lo)
                high.append(hi)
            self.action_terms[term.name] = slice(start, len(names))
        self.action_joint_names = tuple(names)
        self.action_dim = len(names)
        # Which columns each phase commands (the others hold), and whether the phase may move the base.
        phases = self.cfg.phases
        owned = np.ones((max(len(phases), 1), max(len(names), 1)), dtype=bool)
        base_free = np.full(max(len(phases), 1), not self.cfg.fixed_base, dtype=bool)
        groups = {t.name: t.group for t in self.cfg.actions}
        for p, ph in enumerate(phases):
            if ph.action_groups is not None:
                for term, cols in self.action_terms.items():
                    owned[p, cols] = groups[term] in ph.action_groups
            base_free[p] = not ph.fixed_base
        self._act_owned = wp.array(owned, dtype=bool)
        self._base_free = wp.array(base_free, dtype=bool)
        wheel_terms = [t for t in self.cfg.actions if t.group == "base"]
        self._wheel_col = self.action_terms[wheel_terms[0].name].start if wheel_terms else -1
        self._act_kind = wp.array(kind, dtype=int)
        self._act_index = wp.array(index, dtype=int)
        self._act_low = wp.array(np.asarray(low, dtype=np.float32), dtype=float)
        self._act_high = wp.array(np.asarray(high, dtype=np.float32), dtype=float)

    def _build_buffers(self) -> None:
        n, lay, cfg = self.num_envs, self.layout, self.cfg
        self.obs_terms = observation_layout(cfg, {ACTION_DIM: self.action_dim, ROBOT_COORDS: lay.robot_coords,
                                                  ARM_JOINTS: len(spec.LEFT_ARM_JOINTS)})
        self.obs_dim = max((s.stop for s in self.obs_terms.values()), default=0)
        n_ent = len(lay.entity_names)
        self.entities = {
            name: Entity(name=name, slot=k, body=lay.entity_body[k], dynamic=lay.entity_body[k] >= 0)
            for k, name in enumerate(lay.entity_names)
        }
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
        default_q = lay.default_q
        self.scenario = None
        if cfg.scenario:
            self.scenario = load_scenario(cfg.scenario)
            default_q = self.scenario.overlay(lay, default_q, task_id=cfg.task_id)
        default_target_q = np.array(default_q, copy=True)
        for name, value in cfg.initial_targets.items():
            default_target_q[lay.joints.coord[name]] = value
        self._default_q = wp.array(default_q, dtype=float)
        self._default_target_q = wp.array(default_target_q, dtype=float)
        self._terminal_q = z((n, lay.coords_per_world), dtype=float)

        ctx = TaskContext()
        ctx.body_q, ctx.body_qd = self.state.body_q, self.state.body_qd
        ctx.joint_q, ctx.joint_qd = self.state.joint_q, self.state.joint_qd
        ctx.joint_target_q, ctx.joint_target_qd = self.control.joint_target_q, self.control.joint_target_qd
        ctx.bodies_per_world = lay.bodies_per_world
        ctx.coords_per_world = lay.coords_per_world
        ctx.dofs_per_world = lay.dofs_per_world
        ctx.robot_coords = lay.robot_coords
        ctx.base_coord = lay.joints.coord["base_x"]
        ctx.leg_coord = lay.joints.coord["leg_joint1"]
        assert [lay.joints.coord[j] - ctx.leg_coord for j in spec.LEG_JOINTS] == list(range(5)), "legs not contiguous"
        ctx.entity_body = wp.array(lay.entity_body or [-1], dtype=int)
        ctx.entity_coord = wp.array(lay.entity_coord or [-1], dtype=int)
        ctx.entity_dof = wp.array(lay.entity_dof or [-1], dtype=int)
        ctx.entity_static_pose = wp.array(lay.entity_static_pose or [(0, 0, 0, 0, 0, 0, 1)], dtype=wp.transform)
        ctx.entity_half_extents = wp.array(lay.entity_half_extents or [(0, 0, 0)], dtype=wp.vec3)
        arm = cfg.arm
        ctx.tcp_body = lay.joints.body[spec.END_EFFECTOR_LINK[arm]]
        ctx.tcp_offset = wp.transform(wp.vec3(*spec.TCP_OFFSET_POS), wp.quat(*spec.TCP_OFFSET_QUAT))
        ctx.gripper_coord = lay.joints.coord[f"{arm}_gripper_joint"]
        arm_joints = spec.LEFT_ARM_JOINTS if arm == "left" else spec.RIGHT_ARM_JOINTS
        ctx.arm_coords = wp.array([lay.joints.coord[j] for j in arm_joints], dtype=int)
        ctx.arm_home = wp.array(np.asarray(cfg.arm_home, dtype=np.float32), dtype=float)
        ctx.command = z((n, max(cfg.command_dim, 1)), dtype=float)
        ctx.actions = self._actions
        ctx.prev_actions = z((n, self.action_dim), dtype=float)
        ctx.episode_step = z(n, dtype=int)
        ctx.phase = z(n, dtype=int)
        ctx.hold = z((n, max(cfg.hold_slots, 1)), dtype=int)
        self._ctx = ctx

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
        wp.launch(
            apply_actions,
            dim=(self.num_envs, self.action_dim),
            inputs=[
                self._actions,
                self._act_kind,
                self._act_index,
                self._act_low,
                self._act_high,
                self._act_owned,
                self._ctx.phase,
                self.layout.coords_per_world,
                self.layout.dofs_per_world,
                self.control.joint_target_q,
                self.control.joint_target_qd,
            ],
        )

    def _drive_base(self) -> None:
        lin, yaw = wheel_gains()
        joints = self.layout.joints
        wp.launch(
            drive_base,
            dim=self.num_envs,
            inputs=[
                self._actions,
                self._wheel_col,
                self._act_low,
                self._act_high,
                self._act_owned,
                self._base_free,
                self._ctx.phase,
                lin,
                yaw,
                joints.coord["base_x"],
                joints.dof["base_x"],
                self.layout.coords_per_world,
                self.layout.dofs_per_world,
                self.state.joint_q,
                self.control.joint_target_qd,
            ],
        )

    def _simulate(self) -> None:
        for _ in range(self.cfg.decimation):
            if self._wheel_col >= 0:
                self._drive_base()  # per substep: the world-frame twist follows the turning base
            self.solver.step(self.state, self.state, self.control, None, self.cfg.sim_dt)

    def _evaluate_task(self) -> None:
        wp.launch(
            self._task_kernel,
            dim=self.num_envs,
            inputs=[self._ctx, self.cfg.max_episode_steps],
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
        wp.launch(
            fuse.world_to_articulation_mask,
            dim=self.model.articulation_count,
            inputs=[mask, self.model.articulation_world, self._art_mask],
        )
        newton.eval_fk(self.model, self.state.joint_q, self.state.joint_qd, self.state, mask=self._art_mask)
        warmstart = self.solver.mjw_data.qacc_warmstart
        wp.launch(fuse.clear_solver_warmstart, dim=warmstart.shape, inputs=[mask, warmstart])

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
        wp.launch(fuse.keep_terminal_coords, dim=self._terminal_q.shape,
                  inputs=[self._done, self.state.joint_q, self._terminal_q])
        self._reset_rows(self._done)
        self._observe()

    def step(self, actions: torch.Tensor):
        """Advance every row one control step.

        Args:
            actions: (num_envs, action_dim) float32 tensor on the env's device; columns follow
                ``action_joint_names`` (absolute joint targets [rad], gripper 0 open .. 1.2 closed).

        Returns:
            ``(obs, reward, terminated, truncated, info)`` as torch views of the env's Warp buffers
            (overwritten by the next step). Rows that finished were reset in the same step: ``obs`` is
            their new episode's first observation, and ``info`` holds the finished episode's
            ``success``, ``termination_reason``, ``episode_length`` and ``step_signals`` (subtask
            signals of the state the step reached; ``info["signals"]`` belong to ``obs``).
        """
        self.actions.copy_(self.check_actions(actions))
        if self._graph is not None:
            wp.capture_launch(self._graph)
        else:
            with wp.ScopedDevice(self.device):
                self._step_body()
        return self.obs, self.reward, self.terminated, self.truncated, self.info

    def reset(self, env_ids=None):
        """Reset the given rows (all when ``None``); other rows are untouched. Returns ``(obs, info)``."""
        mask = np.zeros(self.num_envs, dtype=bool)
        if env_ids is None:
            mask[:] = True
        else:
            ids = np.asarray(torch.as_tensor(env_ids).cpu(), dtype=np.int64).reshape(-1)
            if ids.size and (ids.min() < 0 or ids.max() >= self.num_envs):
                raise ValueError(f"env_ids must lie in [0, {self.num_envs}), got {ids.tolist()}")
            mask[ids] = True
        self._reset_mask.assign(mask)
        with wp.ScopedDevice(self.device):
            wp.launch(fuse.keep_terminal_coords, dim=self._terminal_q.shape,
                      inputs=[self._reset_mask, self.state.joint_q, self._terminal_q])
            self._reset_rows(self._reset_mask)
            self._observe()
        return self.obs, self.info

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
        """An action that holds every commanded joint at its current drive target."""
        tq = wp.to_torch(self.control.joint_target_q).view(self.num_envs, -1)
        out = torch.zeros(self.num_envs, self.action_dim, device=self.torch_device)
        coords = self.layout.joints.coord
        for c, name in enumerate(self.action_joint_names):
            if name not in spec.BASE_WHEEL_JOINTS:
                out[:, c] = tq[:, coords[name]]
        return out

    def collect(self, *, agent, episodes: int, path, max_steps: int = 1000, progress: bool = True, **kwargs):
        """Run ``agent`` for ``episodes`` episodes and write them to ``path``; returns a ``DatasetRef``
        whose metadata is the run summary (see ``newton_lab.envs.rollout.collect``)."""
        return rollout.collect(self, agent=agent, episodes=episodes, path=path, max_steps=max_steps, progress=progress,
                       **kwargs)

    def evaluate(self, *, agent, episodes: int, max_steps: int = 1000, progress: bool = True, **kwargs):
        """Run ``agent`` for ``episodes`` episodes and report success rate and lengths (see ``rollout``)."""
        return rollout.evaluate(self, agent=agent, episodes=episodes, max_steps=max_steps, progress=progress, **kwargs)
