"""TaskFlowAgent: drive a coherent (multi-phase) task with one agent per phase; TargetSwitchAgent: a phase whose
component option differs per row (``PhaseCfg.target_option``) runs the component's agent for each row's value."""

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
        """Default phase agents come from the component tasks; ``agents`` overrides some by phase name, or by kind
        (one agent for every phase of that kind, ``PhaseCfg.kind``)."""
        phases = env.cfg.phases
        if not phases:
            raise ValueError(f"{env.task_id} is not a coherent task (it has no phases); use its own expert agent")
        agents = _by_phase_name(phases, dict(agents or {}))
        unknown = sorted(set(agents) - {p.name for p in phases})
        if unknown:
            raise ValueError(
                f"agents for unknown phase(s) {unknown}; phases of {env.task_id}: {[p.name for p in phases]}"
            )
        shared: dict[tuple, BaseAgent] = {}  # phases running the same component share its expert
        chosen = []
        for p in phases:
            if p.name in agents:
                chosen.append(agents[p.name])
                continue
            key = (p.task_id, p.target_option)
            if key not in shared:
                shared[key] = (
                    TargetSwitchAgent.of_component(p.task_id, p.target_option, env.cfg.options)
                    if p.target_option
                    else expert_agent(p.task_id, **env.cfg.options)
                )
            chosen.append(shared[key])
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
        for agent, indices in self._phases_by_agent():  # an agent several phases share acts once, for all their rows
            mine = rows[np.isin(phase[rows], indices)]
            if mine.size:
                idx = torch.as_tensor(mine, device=env.torch_device)
                out[idx] = agent.act(env, mine)[idx]
        self._phase[rows] = phase[rows]
        return out

    def _phases_by_agent(self) -> list[tuple[BaseAgent, list[int]]]:
        """Each distinct phase agent with the phases it runs, in first-phase order."""
        groups: dict[int, tuple[BaseAgent, list[int]]] = {}
        for p, agent in enumerate(self.phase_agents):
            groups.setdefault(id(agent), (agent, []))[1].append(p)
        return list(groups.values())

    def done(self, env) -> torch.Tensor:
        """Rows in the last phase whose agent is done."""
        phase = env.info["phase"]
        last = len(self.phase_agents) - 1
        return (phase == last) & self.phase_agents[last].done(env)


def _by_phase_name(phases, agents: dict[str, BaseAgent]) -> dict[str, BaseAgent]:
    """``agents`` keyed by phase name: an agent given for a kind goes to every phase of that kind."""
    kinds = {p.kind for p in phases if p.kind} - {p.name for p in phases}
    out = {key: agent for key, agent in agents.items() if key not in kinds}
    for p in phases:
        if p.kind in kinds and p.kind in agents:
            out.setdefault(p.name, agents[p.kind])
    return out


class TargetSwitchAgent(BaseAgent):
    """One agent per value of a component option (``choices``, in order), each acting for the rows whose value it
    is: a row's value is the argmax of the env's observation term named ``option`` (its one-hot)."""

    def __init__(self, option: str, agents: dict[str, BaseAgent]):
        if not agents:
            raise ValueError(f"TargetSwitchAgent for {option!r} needs one agent per value; got none")
        self.option = option
        self.agents = dict(agents)

    @classmethod
    def of_component(cls, task_id: str, option: str, options: dict | None = None) -> TargetSwitchAgent:
        """The expert of component ``task_id`` for each value of its option ``option`` (the other ``options`` as
        given)."""
        declared = {o.name: o for o in lookup(task_id).options}
        if option not in declared or not declared[option].choices:
            raise ValueError(
                f"{task_id} has no option {option!r} with choices; a phase's target_option names one of "
                f"{sorted(n for n, o in declared.items() if o.choices)}"
            )
        base = dict(options or {})
        return cls(option, {c: expert_agent(task_id, **{**base, option: c}) for c in declared[option].choices})

    def setup(self, env) -> None:
        term = env.task.obs_terms.get(self.option)
        if term is None or term.stop - term.start != len(self.agents):
            raise ValueError(
                f"{env.task_id} needs an observation term {self.option!r} of {len(self.agents)} columns (the "
                f"one-hot of {list(self.agents)}) for its phases' per-row {self.option}"
            )
        self._cols = slice(term.start, term.stop)

    def targets(self, env) -> np.ndarray:
        """(num_envs,) index of each row's value in ``choices``."""
        return env.obs[:, self._cols].argmax(dim=1).cpu().numpy()

    def act(self, env, env_ids=None) -> torch.Tensor:
        rows = as_rows(env_ids, env.num_envs)
        self.fresh_rows(env, rows)
        target = self.targets(env)
        out = env.current_action()
        for i, agent in enumerate(self.agents.values()):
            mine = rows[target[rows] == i]
            if mine.size:
                idx = torch.as_tensor(mine, device=env.torch_device)
                out[idx] = agent.act(env, mine)[idx]
        return out

    def reset(self, env_ids=None) -> None:
        super().reset(env_ids)
        for agent in self.agents.values():
            agent.reset(env_ids)

    def done(self, env) -> torch.Tensor:
        """Each row's own agent's ``done``."""
        if self.bound_env is not env:
            return torch.zeros(env.num_envs, dtype=torch.bool, device=env.torch_device)
        target = torch.as_tensor(self.targets(env), device=env.torch_device)
        out = torch.zeros(env.num_envs, dtype=torch.bool, device=env.torch_device)
        for i, agent in enumerate(self.agents.values()):
            out |= (target == i) & agent.done(env)
        return out
