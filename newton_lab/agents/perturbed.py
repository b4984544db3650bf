"""``PerturbedAgent``: any agent, evaluated under the agent-side perturbations of ``task_api.perturbations``
(action noise, action latency, start-posture noise), and ``perturbation_table``: one evaluation per cell of a
``--perturb`` request, the env-side axes (physics, cameras, light) written into the env for the cell's episodes by
``envs.perturb.perturbed`` and put back after.

The agent-side perturbations sit between the agent and the env, so they apply to every agent (an expert, a diffusion
policy, a PPO actor) and every task without touching either: the agent sees the env as it is, the env gets the
perturbed actions, and the start posture is moved before the agent first looks at a new episode.
"""

from __future__ import annotations

import sys
from collections import deque
from typing import Any

import numpy as np
import torch

from ..envs.perturb import ENV_KINDS, SCENE_KINDS, built_with, perturbed, scene_axes
from ..task_api.perturbations import AXES, Cell
from .base import BaseAgent


def joint_target_columns(env) -> list[int]:
    """Action columns that are joint targets (absolute or relative; not grippers, not wheel speeds)."""
    kinds = env.joints.binding.actions.kinds
    return [
        c
        for c, (kind, name) in enumerate(zip(kinds, env.action_joint_names))
        if kind in ("absolute", "relative") and "gripper" not in name
    ]


class PerturbedAgent(BaseAgent):
    """``agent`` under ``values`` (axis name -> level in the axis's unit; see ``task_api.perturbations.AXES``),
    its noise drawn from ``seed``."""

    def __init__(self, agent: BaseAgent, values: dict[str, float], seed: int = 0) -> None:
        self.agent, self.values, self.seed = agent, dict(values), seed
        self.done_reason = agent.done_reason

    def setup(self, env) -> None:
        self.columns = torch.tensor(joint_target_columns(env), dtype=torch.long, device=env.torch_device)
        self.joint_names = [env.action_joint_names[c] for c in self.columns.tolist()]
        self.generator = torch.Generator(device=env.torch_device).manual_seed(self.seed)
        self.latency = int(self.values.get("action_latency", 0))
        self.history: deque[torch.Tensor] = deque(maxlen=self.latency + 1)

    def _uniform(self, shape, level: float, device) -> torch.Tensor:
        return (torch.rand(shape, generator=self.generator, device=device) * 2.0 - 1.0) * level

    def act(self, env, env_ids=None) -> torch.Tensor:
        fresh = self.fresh_rows(env, env_ids)
        rows = torch.as_tensor(fresh, device=env.torch_device)
        level = self.values.get("posture_noise", 0.0)
        if level and len(fresh) and len(self.joint_names):
            start = env.joints.positions(self.joint_names)[rows]
            moved = start + self._uniform(start.shape, level, env.torch_device)
            env.joints.set_positions(self.joint_names, moved, env_ids=fresh)
        actions = self.agent.act(env, env_ids).clone()
        std = self.values.get("action_noise", 0.0)
        if std and len(self.columns):
            noise = (
                torch.randn((actions.shape[0], len(self.columns)), generator=self.generator, device=actions.device)
                * std
            )
            actions[:, self.columns] += noise
        if not self.latency:
            return actions
        if not self.history:  # the first step: the queue starts full of the first actions
            self.history.extend(actions.clone() for _ in range(self.latency))
        elif len(fresh):  # a new episode starts from its own first action, not the last episode's
            for past in self.history:
                past[rows] = actions[rows]
        self.history.append(actions)
        return self.history[0].clone()

    def reset(self, env_ids=None) -> None:
        """Forget rows (theirs and the agent's): their next episode starts with fresh noise and latency queues."""
        super().reset(env_ids)
        self.agent.reset(env_ids)

    def done(self, env) -> torch.Tensor:
        return self.agent.done(env)

    def holding(self) -> np.ndarray | None:
        return self.agent.holding()


def usable_cells(env, cells: list[Cell]) -> list[Cell]:
    """``cells`` without the swept camera and light cells when ``env`` renders no cameras (they would change
    nothing; a cell asked for by name is refused by ``envs.perturb`` instead)."""
    if env.sensors.camera_specs:
        return cells
    blind = [c for c in cells if c.swept and any(AXES[a].acts_on in ("camera", "surface", "light") for a in c.values)]
    if blind:
        print(f"skipping {len(blind)} camera and light cells: this env renders no cameras", file=sys.stderr)
    return [c for c in cells if c not in blind]


def perturbation_table(
    env, agent: BaseAgent, cells: list[Cell], *, seed: int = 0, on_step=None, rebuild=None, **rollout: Any
) -> list[dict[str, Any]]:
    """One ``env.evaluate`` of ``agent`` per cell (``rollout``: its keywords, e.g. episodes, max_steps), each on the
    same episodes (the env perturbed, then reseeded with ``seed``; put back after): a row per cell with its label,
    the perturbed values and the success. A cell whose scene (``envs.perturb.SCENE_KINDS``: distractor objects)
    differs from ``env``'s runs on ``rebuild(**scene)``'s ``(env, agent)`` (built once per scene, and not seen by
    ``on_step``, which watches ``env``); without ``rebuild`` such a cell is refused in one line."""
    rows, built = [], {tuple(sorted(built_with(env).items())): (env, agent)}
    for cell in usable_cells(env, cells):
        scene = {**built_with(env), **scene_axes(cell.values)}
        key = tuple(sorted(scene.items()))
        if key not in built and rebuild is not None:
            built[key] = rebuild(**scene)
        env_c, agent_c = built.get(key, (env, agent))
        with perturbed(env_c, cell.values, seed=seed):
            env_c.reseed(seed)
            on_agent = {k: v for k, v in cell.values.items() if AXES[k].acts_on not in (*ENV_KINDS, *SCENE_KINDS)}
            wrapped = PerturbedAgent(agent_c, on_agent, seed=seed) if on_agent else agent_c
            s = env_c.evaluate(agent=wrapped, on_step=on_step if env_c is env else None, **rollout)
        rows.append(
            {
                "perturbation": cell.label,
                "values": cell.values,
                "episodes": s["episodes"],
                "successes": s["successes"],
                "success_rate": s["success_rate"],
                "termination_reasons": s["termination_reasons"],
                "summary": s,
            }
        )
    return rows


def evaluate_perturbed(
    env, agent: BaseAgent, cells: list[Cell], *, seed: int = 0, on_step=None, rebuild=None, **rollout: Any
) -> dict[str, Any]:
    """``env.evaluate`` of ``agent`` when ``cells`` is empty; else the perturbation table's last cell's summary with
    the table under ``"perturbations"`` (its rows without their summaries), which also prints as text. ``rebuild``:
    as ``perturbation_table``'s."""
    if not cells:
        return env.evaluate(agent=agent, on_step=on_step, **rollout)
    rows = perturbation_table(env, agent, cells, seed=seed, on_step=on_step, rebuild=rebuild, **rollout)
    for r in rows:
        print(
            f"{r['perturbation']:<24} {r['successes']:>5} / {r['episodes']:<5} {r['success_rate']:.0%}", file=sys.stderr
        )
    return {**rows[-1]["summary"], "perturbations": [{k: v for k, v in r.items() if k != "summary"} for r in rows]}
