"""TaskFlowAgent: drive a coherent (multi-phase) task with one agent per phase."""

from __future__ import annotations

import numpy as np
import torch

from ..task_api.registry import lookup
from .base import BaseAgent, as_rows
from .experts import agent_for_declaration


def expert_agent(task, **options) -> BaseAgent:
    """The expert of a task: ``expert_agent(env)`` for an env's task (a ``TaskFlowAgent`` running the component
    experts phase by phase for a coherent task), or ``expert_agent(task_id, **options)`` for a registered
    component task, built for the task ``options`` it declares (others are ignored)."""
    if isinstance(task, str):
        spec = lookup(task)
        return agent_for_declaration(spec.make_expert(spec.accepted(options)))
    if task.cfg.phases:
        return TaskFlowAgent.from_env(task)
    return expert_agent(task.task_id, **task.cfg.options)


class TaskFlowAgent(BaseAgent):
    """Reads each row's phase, lets that phase's agent act for those rows, and merges the results into the
    full action tensor. A row entering a phase (or starting an episode) resets that phase's agent for it
    alone. Phase agents act on the coherent env itself: they address columns by joint name."""

    def __init__(self, phase_agents: list[BaseAgent], phase_names: list[str] | None = None):
        self.phase_agents = list(phase_agents)
        self.phase_names = list(phase_names or [f"phase{i}" for i in range(len(phase_agents))])

    @classmethod
    def from_env(cls, env, agents: dict[str, BaseAgent] | None = None) -> TaskFlowAgent:
        """Default phase agents come from the component tasks; ``agents`` overrides some by phase name."""
        phases = env.cfg.phases
        if not phases:
            raise ValueError(f"{env.task_id} is not a coherent task (it has no phases); use its own expert agent")
        agents = dict(agents or {})
        unknown = sorted(set(agents) - {p.name for p in phases})
        if unknown:
            raise ValueError(
                f"agents for unknown phase(s) {unknown}; phases of {env.task_id}: {[p.name for p in phases]}"
            )
        chosen = [agents.get(p.name) or expert_agent(p.task_id, **env.cfg.options) for p in phases]
        return cls(chosen, [p.name for p in phases])

    def setup(self, env) -> None:
        self._phase = np.full(env.num_envs, -1, dtype=np.int64)

    def act(self, env, env_ids=None) -> torch.Tensor:
        rows = as_rows(env_ids, env.num_envs)
        fresh = self.fresh_rows(env, rows)
        self._phase[fresh] = -1
        phase = env.info["phase"].cpu().numpy()
        entered = rows[phase[rows] != self._phase[rows]]
        out = env.current_action()
        for p, agent in enumerate(self.phase_agents):
            new = entered[phase[entered] == p]
            if new.size:
                agent.reset(new)
            mine = rows[phase[rows] == p]
            if mine.size:
                idx = torch.as_tensor(mine, device=env.torch_device)
                out[idx] = agent.act(env, mine)[idx]
        self._phase[rows] = phase[rows]
        return out

    def done(self, env) -> torch.Tensor:
        """Rows in the last phase whose agent is done."""
        phase = env.info["phase"]
        last = len(self.phase_agents) - 1
        return (phase == last) & self.phase_agents[last].done(env)
