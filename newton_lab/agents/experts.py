"""A task's expert as an agent, and the agents that compose others per row.

``expert_agent`` gives a task's expert: a registered component task's declaration (``newton_lab.task_api.experts``)
turned into its agent by ``agent_for_declaration`` (a motion plan's planner, a nav agent, ``JointTargetAgent``,
``SequenceAgent``), or for a coherent (multi-phase) task a ``TaskFlowAgent`` with one agent per phase; a phase whose
component option differs per row (``PhaseCfg.target_option``) runs a ``TargetSwitchAgent`` of the component's agents.
The composing agents take any agents (``phase_policy_agent`` puts trained policies in some phases)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from ..task_api.experts import Expert, JointTargetExpert, NavExpert, SequenceExpert
from ..task_api.motion_plan import MotionPlan
from ..task_api.registry import lookup
from .base import BaseAgent, as_rows
from .nav import ProportionalNavAgent, TrajectoryNavAgent
from .planner.agent import PlannerAgent


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


def agent_for_declaration(expert: Expert) -> BaseAgent:
    """The agent that executes ``expert``."""
    if isinstance(expert, MotionPlan):
        return PlannerAgent(expert)
    if isinstance(expert, NavExpert):
        kwargs = dict(
            success_radius=expert.success_radius,
            yaw_tolerance=expert.yaw_tolerance,
            rotate_before_translate=expert.rotate_before_translate,
        )
        if expert.waypoint_spacing is None:
            return ProportionalNavAgent(expert.goal, expert.goal_yaw, **kwargs)
        return TrajectoryNavAgent(expert.goal, expert.goal_yaw, waypoint_spacing=expert.waypoint_spacing, **kwargs)
    if isinstance(expert, JointTargetExpert):
        return JointTargetAgent(
            expert.targets, max_step=expert.max_step, tolerance=expert.tolerance, hold_steps=expert.hold_steps
        )
    if isinstance(expert, SequenceExpert):
        return SequenceAgent([SequenceStep(name, agent_for_declaration(e)) for name, e in expert.steps])
    raise TypeError(
        f"unknown expert declaration {type(expert).__name__}; use a MotionPlan, NavExpert, "
        "JointTargetExpert or SequenceExpert"
    )


class JointTargetAgent(BaseAgent):
    """Drive ``targets`` (joint name -> position [rad | m]); every other column holds its current target.

    With ``max_step`` the command moves from the current targets toward ``targets`` with all joints scaled so
    that the largest remaining error moves at most ``max_step`` per control step. ``done``: every named joint
    within ``tolerance`` of its target for ``hold_steps`` consecutive checks.
    """

    def __init__(
        self, targets: dict[str, float], *, max_step: float | None = None, tolerance: float = 0.12, hold_steps: int = 1
    ):
        if not targets:
            raise ValueError("JointTargetAgent needs at least one joint target")
        self.targets = {str(k): float(v) for k, v in targets.items()}
        self.max_step = None if max_step is None else float(max_step)
        self.tolerance = float(tolerance)
        self.hold_steps = int(hold_steps)

    def setup(self, env) -> None:
        names = list(env.action_joint_names)
        missing = [j for j in self.targets if j not in names]
        if missing:
            raise ValueError(f"env {env.task_id} has no action columns for {missing}; its columns are {names}")
        self._cols = [names.index(j) for j in self.targets]
        self._goal = torch.tensor(list(self.targets.values()), device=env.torch_device)
        self._held = torch.zeros(env.num_envs, dtype=torch.long, device=env.torch_device)

    def reset(self, env_ids=None) -> None:
        super().reset(env_ids)
        if self.bound_env is not None:
            self._held[slice(None) if env_ids is None else torch.as_tensor(env_ids, device=self._held.device)] = 0

    def act(self, env, env_ids=None) -> torch.Tensor:
        self.bind(env)
        out = env.current_action()
        cmd = out[:, self._cols]
        if self.max_step is None:
            cmd = self._goal.expand_as(cmd).clone()
        else:
            err = self._goal - cmd
            scale = torch.clamp(self.max_step / err.abs().amax(dim=1, keepdim=True).clamp_min(1e-9), max=1.0)
            cmd = cmd + err * scale
        out[:, self._cols] = cmd
        return out

    def done(self, env) -> torch.Tensor:
        self.bind(env)
        q = env.joints.positions(list(self.targets))
        ok = ((q - self._goal).abs() <= self.tolerance).all(dim=1)
        self._held = torch.where(ok, self._held + 1, torch.zeros_like(self._held))
        return self._held >= self.hold_steps


@dataclass
class SequenceStep:
    name: str
    agent: BaseAgent
    done: Callable | None = None
    """``done(env) -> (num_envs,) bool``; ``None`` uses ``agent.done``."""


class SequenceAgent(BaseAgent):
    """Runs ``steps`` in order for every row. Each call, a row's current step's agent acts for it; when the
    step's predicate holds, that row moves on and only its next agent is reset (for that row). A row past the
    last step holds its current targets. ``done``: every step finished."""

    def __init__(self, steps: list[SequenceStep]):
        if not steps:
            raise ValueError("SequenceAgent needs at least one step")
        self.steps = list(steps)

    def setup(self, env) -> None:
        self._step = np.zeros(env.num_envs, dtype=np.int64)

    def current_step(self) -> np.ndarray:
        """(num_envs,) index of each row's step (``len(steps)`` when finished)."""
        return self._step.copy()

    def act(self, env, env_ids=None) -> torch.Tensor:
        fresh = self.fresh_rows(env, env_ids)
        if fresh.size:
            self._step[fresh] = 0
            self.steps[0].agent.reset(fresh)
        rows = as_rows(env_ids, env.num_envs)
        out = env.current_action()
        for k, step in enumerate(self.steps):
            mine = rows[self._step[rows] == k]
            if mine.size:
                idx = torch.as_tensor(mine, device=env.torch_device)
                out[idx] = step.agent.act(env, mine)[idx]
        # advance rows whose step finished (at most one step per call); the next agent starts fresh for
        # those rows only
        before = self._step.copy()
        for k, step in enumerate(self.steps):
            mine = rows[before[rows] == k]
            if not mine.size:
                continue
            finished = _done_mask(step, env)[mine]
            moved = mine[finished]
            if moved.size:
                self._step[moved] = k + 1
                if k + 1 < len(self.steps):
                    self.steps[k + 1].agent.reset(moved)
        return out

    def done(self, env) -> torch.Tensor:
        if self.bound_env is not env:
            return torch.zeros(env.num_envs, dtype=torch.bool, device=env.torch_device)
        return torch.as_tensor(self._step >= len(self.steps), device=env.torch_device)


def _done_mask(step: SequenceStep, env) -> np.ndarray:
    """The step's done predicate as a (num_envs,) bool array; any other shape or dtype is refused."""
    mask = torch.as_tensor((step.done or step.agent.done)(env))
    if tuple(mask.shape) != (env.num_envs,) or mask.dtype != torch.bool:
        raise ValueError(
            f"done of sequence step {step.name!r} must be a ({env.num_envs},) bool tensor, got "
            f"{tuple(mask.shape)} {mask.dtype}; return one flag per env row"
        )
    return mask.cpu().numpy()


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
