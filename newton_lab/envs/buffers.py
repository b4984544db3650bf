"""``NewtonEnv``'s device buffers: the step's preallocated arrays (``StepBuffers``), the entity table, the reset
coordinates and the task context.

The task context has two halves: the simulation and task half filled here (state / control arrays, per-world
sizes, entities, task command and per-row counters) and the robot half the binding fills
(``robots.bound.RobotContext.fill``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import newton
import numpy as np
import warp as wp

from ..kernels.context import TaskContext
from ..robots.bound import BoundRobot
from ..task_api.cfg import TaskCfg
from .scenario import Scenario, load_scenario
from .scene import SceneLayout


@dataclass(frozen=True)
class Entity:
    """A named rigid object of the scene; ``slot`` indexes ``env.buffers.entity_poses``."""

    name: str
    slot: int
    body: int
    """World-local body index, -1 for a static collider."""
    dynamic: bool
    coord: int = -1
    """World-local first coordinate of a free body's pose (x, y, z, qx, qy, qz, qw in a row of ``joint_q``),
    -1 for a static collider."""


def entity_table(layout: SceneLayout) -> dict[str, Entity]:
    """The scene's entities by name, in slot order."""
    return {
        name: Entity(
            name=name,
            slot=k,
            body=layout.entity_body[k],
            dynamic=layout.entity_body[k] >= 0,
            coord=layout.entity_coord[k],
        )
        for k, name in enumerate(layout.entity_names)
    }


@dataclass(frozen=True)
class StepBuffers:
    """The step's preallocated per-row Warp arrays (on the env's device); the env's torch views (``obs``,
    ``reward``, ``info[...]``, ...) share their memory. Sizes that may be 0 are allocated with at least 1 column."""

    actions: wp.array2d
    """(num_envs, action_dim) the actions of the step (``env.buffers.actions``)."""
    obs: wp.array2d
    """(num_envs, obs_dim) observation after the step (and its resets)."""
    final_obs: wp.array2d
    """(num_envs, obs_dim) observation of the state the step reached, before its resets."""
    reward: wp.array
    terminated: wp.array
    truncated: wp.array
    done: wp.array
    """Terminated or truncated (the rows the step reset)."""
    success: wp.array
    success_latched: wp.array
    reason: wp.array
    """Termination reason index (``env.task.termination_reasons``)."""
    episode_length: wp.array
    signals: wp.array2d
    """(num_envs, signals) subtask signals of ``obs``'s state."""
    step_signals: wp.array2d
    """(num_envs, signals) subtask signals of the state the step reached."""
    episode_count: wp.array
    """(num_envs,) episodes started per row (keys the seeded reset draws)."""
    reset_mask: wp.array
    """(num_envs,) rows a ``reset`` call resets."""
    articulation_mask: wp.array
    """(articulations,) articulations of the rows being reset (forward kinematics)."""
    tcp_pose: wp.array2d
    entity_poses: wp.array3d
    terminal_q: wp.array2d
    """(num_envs, coords_per_world) coordinates of each row's last finished episode."""

    @classmethod
    def allocate(
        cls,
        *,
        num_envs: int,
        action_dim: int,
        obs_dim: int,
        signals: int,
        entities: int,
        articulations: int,
        coords_per_world: int,
    ) -> StepBuffers:
        n, z = num_envs, wp.zeros
        return cls(
            actions=z((n, action_dim), dtype=float),
            obs=z((n, max(obs_dim, 1)), dtype=float),
            final_obs=z((n, max(obs_dim, 1)), dtype=float),
            reward=z(n, dtype=float),
            terminated=z(n, dtype=bool),
            truncated=z(n, dtype=bool),
            done=z(n, dtype=bool),
            success=z(n, dtype=bool),
            success_latched=z(n, dtype=bool),
            reason=z(n, dtype=int),
            episode_length=z(n, dtype=int),
            signals=z((n, max(signals, 1)), dtype=float),
            step_signals=z((n, max(signals, 1)), dtype=float),
            episode_count=z(n, dtype=int),
            reset_mask=z(n, dtype=bool),
            articulation_mask=z(articulations, dtype=bool),
            tcp_pose=z((n, 7), dtype=float),
            entity_poses=z((n, max(entities, 1), 7), dtype=float),
            terminal_q=z((n, coords_per_world), dtype=float),
        )

    def info(self, ctx: TaskContext, *, signals: int, command_dim: int) -> dict[str, Any]:
        """The ``info`` dict of ``env.step`` / ``env.reset``: torch views of these arrays and of the context's
        phase and command."""
        t = wp.to_torch
        return {
            "success": t(self.success),
            "success_latched": t(self.success_latched),
            "done": t(self.done),
            "termination_reason": t(self.reason),
            "episode_length": t(self.episode_length),
            "phase": t(ctx.phase),
            "signals": t(self.signals)[:, :signals],
            # the same signals on the state the step reached, before an automatic reset replaced it
            "step_signals": t(self.step_signals)[:, :signals],
            "command": t(ctx.command)[:, :command_dim],
        }


def reset_coordinates(cfg: TaskCfg, layout: SceneLayout) -> tuple[Scenario | None, np.ndarray, np.ndarray]:
    """``(scenario, default_q, default_target_q)``: one world's coordinates and drive targets at reset (the
    scene's posture, overlaid by the task's scenario, with the task's ``initial_targets``)."""
    default_q, scenario = layout.default_q, None
    if cfg.scenario:
        scenario = load_scenario(cfg.scenario)
        default_q = scenario.overlay(layout, default_q, task_id=cfg.task_id)
    default_target_q = np.array(default_q, copy=True)
    for name, value in cfg.initial_targets.items():
        default_target_q[layout.joints.coord[name]] = value
    return scenario, default_q, default_target_q


def arm_home(cfg: TaskCfg, arm_joints: int) -> np.ndarray:
    """``cfg.arm_home`` (zeros when empty) as float32, or a one-line ``ValueError`` when its length is not the
    controlled arm's joint count."""
    home = np.asarray(cfg.arm_home or (0.0,) * arm_joints, dtype=np.float32)
    if home.shape != (arm_joints,):
        raise ValueError(
            f"{cfg.task_id}: arm_home has {home.size} values, the {cfg.arm} arm has {arm_joints} joints; "
            f"give one value per joint [rad]"
        )
    return home


def build_context(
    *,
    cfg: TaskCfg,
    layout: SceneLayout,
    binding: BoundRobot,
    state: newton.State,
    control: newton.Control,
    actions: wp.array2d,
    num_envs: int,
) -> TaskContext:
    """The ``TaskContext`` every task term reads (arrays on the current Warp device)."""
    n, lay = num_envs, layout
    ctx = TaskContext()
    ctx.body_q, ctx.body_qd = state.body_q, state.body_qd
    ctx.joint_q, ctx.joint_qd = state.joint_q, state.joint_qd
    ctx.joint_target_q, ctx.joint_target_qd = control.joint_target_q, control.joint_target_qd
    ctx.bodies_per_world = lay.bodies_per_world
    ctx.coords_per_world = lay.coords_per_world
    ctx.dofs_per_world = lay.dofs_per_world
    ctx.entity_body = wp.array(lay.entity_body or [-1], dtype=int)
    ctx.entity_coord = wp.array(lay.entity_coord or [-1], dtype=int)
    ctx.entity_dof = wp.array(lay.entity_dof or [-1], dtype=int)
    ctx.entity_static_pose = wp.array(lay.entity_static_pose or [(0, 0, 0, 0, 0, 0, 1)], dtype=wp.transform)
    ctx.entity_half_extents = wp.array(lay.entity_half_extents or [(0, 0, 0)], dtype=wp.vec3)
    binding.context.fill(ctx)
    ctx.arm_home = wp.array(arm_home(cfg, len(binding.context.arm_coords)), dtype=float)
    ctx.command = wp.zeros((n, max(cfg.command_dim, 1)), dtype=float)
    ctx.actions = actions
    ctx.prev_actions = wp.zeros(actions.shape, dtype=float)
    ctx.episode_step = wp.zeros(n, dtype=int)
    ctx.phase = wp.zeros(n, dtype=int)
    ctx.hold = wp.zeros((n, max(cfg.hold_slots, 1)), dtype=int)
    return ctx
