"""What ``NewtonEnv`` builds its device buffers from: the entity table, the reset coordinates, the task context.

The task context has two halves: the simulation and task half filled here (state / control arrays, per-world
sizes, entities, task command and per-row counters) and the robot half the binding fills
(``robots.g1.binding.RobotContext.fill``).
"""

from __future__ import annotations

from dataclasses import dataclass

import newton
import numpy as np
import warp as wp

from ..kernels.context import TaskContext
from ..robots.g1.binding import G1Binding
from ..task_api.cfg import TaskCfg
from .scenario import Scenario, load_scenario
from .scene import SceneLayout


@dataclass(frozen=True)
class Entity:
    """A named rigid object of the scene; ``slot`` indexes ``env.entity_poses``."""

    name: str
    slot: int
    body: int
    """World-local body index, -1 for a static collider."""
    dynamic: bool


def entity_table(layout: SceneLayout) -> dict[str, Entity]:
    """The scene's entities by name, in slot order."""
    return {
        name: Entity(name=name, slot=k, body=layout.entity_body[k], dynamic=layout.entity_body[k] >= 0)
        for k, name in enumerate(layout.entity_names)
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


def build_context(
    *,
    cfg: TaskCfg,
    layout: SceneLayout,
    binding: G1Binding,
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
    ctx.arm_home = wp.array(np.asarray(cfg.arm_home, dtype=np.float32), dtype=float)
    ctx.command = wp.zeros((n, max(cfg.command_dim, 1)), dtype=float)
    ctx.actions = actions
    ctx.prev_actions = wp.zeros(actions.shape, dtype=float)
    ctx.episode_step = wp.zeros(n, dtype=int)
    ctx.phase = wp.zeros(n, dtype=int)
    ctx.hold = wp.zeros((n, max(cfg.hold_slots, 1)), dtype=int)
    return ctx
