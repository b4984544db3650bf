"""A task's fused kernels and the launches of one env step, in order, on arrays allocated once, so that the whole
sequence records as one Warp graph (a CUDA graph on a GPU, Warp's CPU graph on the CPU).

The task's declared terms give the observation layout (``observation_layout``: each term's columns) and its fused
kernels (``build_task_kernels``, through ``newton_lab.kernels.fuse``). One step:
actions -> control targets (``Actuation.apply``) -> ``decimation`` x (base twist and drive setpoints, then
``solver.step``, in the solver's joint space when joints are welded: ``envs.drive``) -> fused task kernel
(phase, success, terminations, reward) -> subtask signals and observation of the state reached (``final_obs``) and the
finished rows' coordinates -> masked reset of finished rows (+ seeded randomisation, setpoints synced, forward
kinematics, solver warm start cleared) -> observation, signals, poses.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import newton
import warp as wp

from ..kernels import fuse
from ..kernels.context import TaskContext, record_poses
from ..task_api.cfg import BUILTIN_TERMINATION_REASONS, DERIVED_SIZES, TaskCfg
from . import mujoco_substeps
from .buffers import StepBuffers
from .drive import Actuation, SolverJointSpace


def observation_layout(cfg: TaskCfg, derived: dict[str, int]) -> dict[str, slice]:
    """Column slice of every observation term, in declaration order. ``derived`` gives the widths the env
    knows (``action_dim``, ``robot_coords``, ``arm_joints``)."""
    layout, col = {}, 0
    for name, term in cfg.observations.items():
        size = term.size
        if isinstance(size, str):
            if size not in derived:
                raise ValueError(
                    f"observation {name!r} of {cfg.task_id} has size {size!r}; use an int or one of "
                    f"{list(DERIVED_SIZES)}"
                )
            size = derived[size]
        layout[name] = slice(col, col + int(size))
        col += int(size)
    return layout


@dataclass(frozen=True)
class TaskKernels:
    """The fused kernels of one task: step (phase, success, terminations, reward), observation, subtask
    signals (``None`` without signals) and masked reset."""

    task: Any
    observe: Any
    signals: Any
    reset: Any


def build_task_kernels(cfg: TaskCfg, obs_layout: dict[str, slice]) -> TaskKernels:
    """Fuse ``cfg``'s terms into its kernels."""
    clash = sorted(set(cfg.terminations) & set(BUILTIN_TERMINATION_REASONS))
    if clash:
        raise ValueError(
            f"{cfg.task_id}: termination terms may not be named {clash}; those names are the env's "
            f"own reasons {list(BUILTIN_TERMINATION_REASONS)}; rename the terms"
        )
    return TaskKernels(
        task=fuse.build_task_kernel(
            phase_success=cfg.phase_success,
            terminations=[(t.func, t.phase) for t in cfg.terminations.values()],
            rewards=[(t.func, t.weight) for t in cfg.rewards.values()],
            terminate_on_success=cfg.terminate_on_success,
        ),
        observe=fuse.build_observation_kernel(
            [(term.func, obs_layout[name].start) for name, term in cfg.observations.items()]
        ),
        signals=fuse.build_signal_kernel([t.func for t in cfg.signals.values()]) if cfg.signals else None,
        reset=fuse.build_reset_kernel([t.func for t in cfg.events.values()]),
    )


class GraphCaptureWarning(RuntimeWarning):
    """The env step could not be recorded as one graph: it runs its launches eagerly (correct, slower)."""


class StepLaunches:
    """Every launch of an env step and of a masked reset; ``capture`` records ``step`` as one graph. Warp arrays
    live on the current device (callers hold a ``wp.ScopedDevice``). ``seed()`` and ``randomize()`` are read at
    each launch (and baked into a captured graph when it is recorded)."""

    def __init__(
        self,
        *,
        cfg: TaskCfg,
        model: newton.Model,
        state: newton.State,
        solver,
        drive: newton.Control,
        actuation: Actuation,
        ctx: TaskContext,
        buffers: StepBuffers,
        kernels: TaskKernels,
        default_q: wp.array,
        default_target_q: wp.array,
        seed: Callable[[], int],
        randomize: Callable[[], bool],
        joint_space: SolverJointSpace | None = None,
    ):
        self.cfg, self.model, self.state, self.solver, self.drive = cfg, model, state, solver, drive
        self.joint_space = joint_space
        self.actuation, self.ctx, self.buf, self.kernels = actuation, ctx, buffers, kernels
        self.num_envs = buffers.reward.shape[0]
        self.default_q, self.default_target_q = default_q, default_target_q
        self.seed, self.randomize = seed, randomize
        self.control_step_physics = None
        """``envs.mujoco_substeps.ControlStepPhysics`` where ``simulate`` exchanges the state with MuJoCo-Warp
        once a control step (``PhysicsCfg.sync_every_substep`` off); ``None``: every substep is a whole
        ``solver.step``."""
        self._yaw_in_qpos = None  # the base yaw in MuJoCo-Warp's qpos, read by the wheel drive between substeps
        if not cfg.physics.sync_every_substep and mujoco_substeps.supported(solver):
            model_stepped = joint_space.model if joint_space is not None else model
            physics = mujoco_substeps.ControlStepPhysics(solver, model_stepped, cfg.sim_dt)
            yaw = actuation.base_coord + 2
            yaw = joint_space.solver_coord[yaw] if joint_space is not None else yaw
            if actuation.wheel_col >= 0 and yaw >= 0:  # a welded yaw stays what the env's coordinates say
                self._yaw_in_qpos = physics.qpos_source(yaw)
            self.control_step_physics = physics

    def capture(self):
        """Record ``step`` as one graph; ``None`` where the Warp build cannot capture (eager stepping stays
        correct), said in one line (:class:`GraphCaptureWarning`)."""
        try:
            with wp.ScopedCapture(device=self.model.device) as cap:
                self.step()
        except Exception as e:  # noqa: BLE001 - depends on the Warp build; told, not hidden
            reason = " ".join(f"{type(e).__name__}: {e}".split())
            warnings.warn(
                f"{self.cfg.task_id}: the env step could not be captured as a graph ({reason}); "
                "stepping eagerly (correct, slower)",
                GraphCaptureWarning,
                stacklevel=2,
            )
            return None
        return cap.graph

    def apply_actions(self) -> None:
        self.actuation.apply(self.buf.actions, self.ctx.phase)

    def _physics(self) -> None:
        """One substep's drive and solver step; with welded joints the env's body poses are not updated (nothing
        between two substeps reads them): ``substep`` and ``simulate`` do it once at their end."""
        # the world-frame base twist follows the turning base, limited setpoints advance
        self.actuation.substep(self.buf.actions, self.ctx.phase, self.state.joint_q)
        js = self.joint_space
        if js is None:
            self.solver.step(self.state, self.state, self.drive, None, self.cfg.sim_dt)
            return
        js.push(self.state, self.drive)  # welded joints: the solver steps its own, smaller joint space
        self.solver.step(js.state, js.state, js.drive, None, self.cfg.sim_dt)
        js.pull(self.state)

    def _body_poses(self) -> None:
        if self.joint_space is not None:
            self.joint_space.forward_kinematics(self.state)

    def substep(self) -> None:
        self._physics()
        self._body_poses()

    def simulate(self) -> None:
        if self.control_step_physics is None:
            for _ in range(self.cfg.decimation):
                self._physics()
        else:  # nothing reads the coordinates between substeps: push once, pull once (envs.mujoco_substeps)
            physics, js = self.control_step_physics, self.joint_space
            state, drive = (js.state, js.drive) if js is not None else (self.state, self.drive)
            for i in range(self.cfg.decimation):  # the yaw: the env's before the push, then MuJoCo's
                self.actuation.substep(
                    self.buf.actions, self.ctx.phase, self.state.joint_q, self._yaw_in_qpos if i else None
                )
                if js is not None:
                    js.push(self.state, self.drive)  # the new setpoints (the coordinates copied are not read)
                if i == 0:
                    physics.begin(state)
                physics.substep(state, drive)
            physics.end(state)
            if js is not None:
                js.pull(self.state)
        self._body_poses()  # once a control step, not once a substep

    def evaluate_task(self) -> None:
        buf = self.buf
        wp.launch(
            self.kernels.task,
            dim=self.num_envs,
            inputs=[self.ctx, self.cfg.max_episode_steps, wp.vec3(*self.cfg.divergence_bounds)],
            outputs=[
                buf.reward,
                buf.terminated,
                buf.truncated,
                buf.done,
                buf.success,
                buf.success_latched,
                buf.reason,
                buf.episode_length,
            ],
        )

    def keep_terminal_coords(self, mask: wp.array) -> None:
        """The masked rows' coordinates into ``terminal_q`` (before their reset replaces them)."""
        wp.launch(
            fuse.keep_terminal_coords,
            dim=self.buf.terminal_q.shape,
            inputs=[mask, self.state.joint_q, self.buf.terminal_q],
        )

    def reset_rows(self, mask: wp.array) -> None:
        buf = self.buf
        wp.launch(
            self.kernels.reset,
            dim=self.num_envs,
            inputs=[
                self.ctx,
                mask,
                self.default_q,
                self.default_target_q,
                self.seed(),
                int(self.randomize()),
                buf.episode_count,
                buf.success_latched,
            ],
        )
        self.actuation.sync(mask)  # the reset rows' drive setpoints jump to their reset targets
        wp.launch(
            fuse.world_to_articulation_mask,
            dim=self.model.articulation_count,
            inputs=[mask, self.model.articulation_world, buf.articulation_mask],
        )
        newton.eval_fk(self.model, self.state.joint_q, self.state.joint_qd, self.state, mask=buf.articulation_mask)
        data = self.solver.mjw_data  # the reset worlds' solver history (NaN after a divergence) is cleared
        wp.launch(
            fuse.clear_solver_warmstart,
            dim=data.qacc_warmstart.shape,
            inputs=[mask, data.qacc_warmstart, data.qacc, data.qvel],
        )

    def write_signals(self, out: wp.array2d) -> None:
        if self.kernels.signals is not None:
            wp.launch(self.kernels.signals, dim=self.num_envs, inputs=[self.ctx, out])

    def observe(self) -> None:
        buf = self.buf
        wp.launch(self.kernels.observe, dim=self.num_envs, inputs=[self.ctx, buf.obs])
        self.write_signals(buf.signals)
        wp.launch(record_poses, dim=self.num_envs, inputs=[self.ctx, buf.tcp_pose, buf.entity_poses])

    def step(self) -> None:
        buf = self.buf
        self.apply_actions()
        self.simulate()
        self.evaluate_task()
        self.write_signals(buf.step_signals)
        wp.launch(self.kernels.observe, dim=self.num_envs, inputs=[self.ctx, buf.final_obs])
        self.keep_terminal_coords(buf.done)
        self.reset_rows(buf.done)
        self.observe()

    def reset(self, mask: wp.array) -> None:
        """Reset the masked rows (their last coordinates kept in ``terminal_q``) and observe."""
        self.keep_terminal_coords(mask)
        self.reset_rows(mask)
        self.observe()
