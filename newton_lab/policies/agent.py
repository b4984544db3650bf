"""PolicyAgent: runs a trained policy on a batched env with a per-row observation history.

Each row keeps its last ``obs_horizon`` observations (filled with the first observation when the row's
episode starts) and a queue of ``action_horizon`` actions; rows re-plan when their queue runs out, so a
row that resets never disturbs the others.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from ..agents.base import BaseAgent, as_rows
from ..agents.experts import TargetSwitchAgent, TaskFlowAgent
from ..task_api.compose import TARGET_SEPARATOR, target_choices
from ..task_api.registry import lookup
from .diffusion import DiffusionPolicy
from .graphed import GraphedSampler


def _compatible_task(env, policy_task: str | None) -> bool:
    """A policy trained on a task (or on its Mimic data) runs on that task, on its Mimic variant, and as a
    phase agent of a coherent task that has it as a component."""
    if policy_task is None or env.task_id == policy_task:
        return True
    return lookup(env.task_id).source_task == policy_task or policy_task in [p.task_id for p in env.cfg.phases]


def _trained_for_phase(policy_task: str | None, component: str) -> bool:
    """A phase runs the policies of its component task and of that task's Mimic variant."""
    return policy_task is None or policy_task == component or lookup(policy_task).source_task == component


def phase_policy_agent(env, checkpoints, *, device=None, seed: int = 0, graphs: bool = True) -> TaskFlowAgent:
    """A coherent task's agent: the trained policy of ``checkpoints`` (phase name or kind -> checkpoint path; a kind's
    policy runs every phase of that kind; ``kind/value`` -> one per value of the kind's target, switched per row on
    its one-hot, ``TargetSwitchAgent``) in its phase,
    the component's expert in the others (e.g. a learned pick and place with the nav expert between them). Each
    checkpoint is loaded and checked against its phase and the env at once: one line names a phase the task does
    not have, a checkpoint trained for another phase's task, or observation terms / cameras the env lacks."""
    _check_phases(env, checkpoints)
    return compose_phase_policies(
        env,
        {
            name: PolicyAgent.from_checkpoint(path, device=device, seed=seed, graphs=graphs)
            for name, path in checkpoints.items()
        },
        sources=checkpoints,
    )


def _check_phases(env, named) -> dict:
    """The phases by name and by kind (the first phase of each kind: a kind's phases share their component), and
    ``kind/value`` for the per-target names of ``named``; one line for a name the task lacks, or a kind given per
    target without every value, or also as a whole."""
    phases = {p.name: p for p in env.cfg.phases}
    if not phases:
        raise ValueError(f"{env.task_id} has no phases; give one --checkpoint for it instead of phase checkpoints")
    kinds = {kind: env.cfg.phases[ix[0]] for kind, ix in env.cfg.phase_kinds.items()}
    unknown = sorted({n.split(TARGET_SEPARATOR)[0] for n in named} - set(phases) - set(kinds))
    if unknown:
        listed = ", ".join(kinds) if len(kinds) < len(phases) else ", ".join(phases)
        raise ValueError(f"{env.task_id} has no phase {unknown[0]!r}; its phases: {listed}")
    out = {**phases, **kinds}
    for kind, given in _per_target(named).items():
        _, values = target_choices(env.cfg, kind)
        wrong = sorted(set(given) - set(values))
        if wrong:
            raise ValueError(f"phase kind {kind!r} has no target {wrong[0]!r}; its targets: {', '.join(values)}")
        if set(given) != set(values) or kind in named:
            missing = [v for v in values if v not in given]
            raise ValueError(
                f"phase kind {kind!r} takes one policy per target ({kind}/<target>) for all of "
                f"{', '.join(values)}, or one for the kind alone; "
                + (f"missing: {', '.join(missing)}" if missing else f"{kind!r} was given both ways")
            )
        out.update({f"{kind}{TARGET_SEPARATOR}{v}": kinds[kind] for v in values})
    return out


def _per_target(named) -> dict[str, list[str]]:
    """The target values given per kind among the names ``kind/value`` of ``named``."""
    out: dict[str, list[str]] = {}
    for name in named:
        if TARGET_SEPARATOR in name:
            kind, value = name.split(TARGET_SEPARATOR, 1)
            out.setdefault(kind, []).append(value)
    return out


def compose_phase_policies(env, agents: dict[str, PolicyAgent], *, sources=None) -> TaskFlowAgent:
    """``phase_policy_agent`` for policy agents already made (``sources``: phase -> where each came from, for the
    errors)."""
    phases = _check_phases(env, agents)
    for name, agent in agents.items():
        where = (sources or {}).get(name, "policy")
        trained, component = agent.policy.info.get("task_id"), phases[name].task_id
        if not _trained_for_phase(trained, component):
            raise ValueError(
                f"checkpoint {where} was trained for {trained}, but phase {name!r} of {env.task_id} runs "
                f"{component}; give that phase a checkpoint of {component}"
            )
        try:
            agent.bind(env)  # the observation, camera and action checks, now rather than at the first step
        except ValueError as exc:
            raise ValueError(f"phase {name!r} ({where}): {exc}") from None
    composed = {name: agent for name, agent in agents.items() if TARGET_SEPARATOR not in name}
    for kind in _per_target(agents):  # one agent per value, in the order of the target's one-hot
        option, values = target_choices(env.cfg, kind)
        composed[kind] = TargetSwitchAgent(option, {v: agents[f"{kind}{TARGET_SEPARATOR}{v}"] for v in values})
    return TaskFlowAgent.from_env(env, agents=composed)


class PolicyAgent(BaseAgent):
    """Acts with ``policy`` (an object with ``predict_action``, ``obs_keys``, ``info``, ``cfg``)."""

    def __init__(self, policy, *, seed: int = 0, graphs: bool = True):
        self.policy = policy
        self.seed = seed
        self.graphs = graphs
        """On CUDA, sample actions from CUDA graphs (``policies.graphed``); False: eagerly."""

    @classmethod
    def from_checkpoint(cls, path, *, device=None, seed: int = 0, graphs: bool = True) -> PolicyAgent:
        """Load a checkpoint written by ``Policy.from_backend(...).train``; missing / damaged files raise."""
        if not Path(path).exists():
            raise FileNotFoundError(f"checkpoint {path} does not exist; train one first (examples/03_train.py)")
        return cls(DiffusionPolicy.load(path, device=device or "cpu"), seed=seed, graphs=graphs)

    def setup(self, env) -> None:
        p = self.policy
        task = p.info.get("task_id")
        if not _compatible_task(env, task):
            raise ValueError(f"checkpoint was trained for {task} but the env runs {env.task_id}; evaluate it on {task}")
        missing = [k for k in p.obs_keys if k not in env.task.obs_terms]
        if missing:
            raise ValueError(
                f"checkpoint needs observation terms {missing} that {env.task_id} does not provide; "
                f"available: {sorted(env.task.obs_terms)}"
            )
        dims = p.info.get("obs_dims", {})
        wrong = {
            k: (dims[k], env.task.obs_terms[k].stop - env.task.obs_terms[k].start)
            for k in p.obs_keys
            if k in dims and dims[k] != env.task.obs_terms[k].stop - env.task.obs_terms[k].start
        }
        if wrong:
            raise ValueError(f"checkpoint observation sizes (checkpoint, env) {wrong} do not match {env.task_id}")
        self._image_keys = self._check_images(env)
        names = list(p.info.get("action_joint_names", [])) or list(env.action_joint_names)
        if not set(names) <= set(env.action_joint_names):
            raise ValueError(f"checkpoint actions {names} differ from the env's {list(env.action_joint_names)}")
        # a component policy inside a coherent task writes its own columns; the others hold
        cols = [list(env.action_joint_names).index(j) for j in names]
        self._act_cols = None if cols == list(range(env.action_dim)) else torch.as_tensor(cols, device=env.torch_device)
        cols = np.concatenate([np.arange(env.task.obs_terms[k].start, env.task.obs_terms[k].stop) for k in p.obs_keys])
        self._cols = torch.as_tensor(cols, device=env.torch_device)
        n, h, a = env.num_envs, p.cfg.obs_horizon, p.cfg.action_horizon
        self._history = torch.zeros(n, h, len(cols), device=env.torch_device)
        shapes = p.info.get("image_shapes", {})
        self._frames = {
            k: torch.zeros((n, h, *shapes[k]), dtype=torch.uint8, device=env.torch_device) for k in self._image_keys
        }
        self._queue = torch.zeros(n, a, len(names), device=env.torch_device)
        self._cursor = np.full(n, a, dtype=np.int64)
        self._generator = torch.Generator(device="cpu").manual_seed(self.seed)
        self._sampler = GraphedSampler(p, n, enabled=self.graphs) if hasattr(p, "sample_actions") else None

    def _check_images(self, env) -> list[str]:
        """The policy's image keys after checking the env renders them at the trained size (one line otherwise)."""
        keys = list(getattr(self.policy.cfg, "image_keys", None) or ())
        if not keys:
            return []
        terms = env.sensors.image_terms
        missing = [k for k in keys if k not in terms]
        if missing:
            raise ValueError(
                f"checkpoint sees cameras {missing} that this {env.task_id} env does not render "
                f"(its image terms: {sorted(terms) or 'none'}); make the env with its cameras on"
            )
        shapes = self.policy.info.get("image_shapes", {})
        wrong = {
            k: (tuple(shapes[k]), tuple(env.sensors.images[k].shape[1:]))
            for k in keys
            if tuple(shapes[k]) != tuple(env.sensors.images[k].shape[1:])
        }
        if wrong:
            fix = ", ".join(f"'{k.rsplit('_', 1)[0]}': ({s[0][1]}, {s[0][0]})" for k, s in wrong.items())
            raise ValueError(
                f"checkpoint image sizes (trained, env) {wrong} differ (H, W, C); make the env with cameras={{{fix}}}"
            )
        return keys

    def reset(self, env_ids=None) -> None:
        """Forget the history of ``env_ids`` (all rows when ``None``); they refill at the next ``act``."""
        super().reset(env_ids)

    def act(self, env, env_ids=None) -> torch.Tensor:
        """The next action of every row; the rows of ``env_ids`` (all when ``None``) re-plan when their queue has
        run out (the others' actions are the env's held ones or stale: the caller uses only ``env_ids``)."""
        fresh = self.fresh_rows(env)
        obs = env.obs[:, self._cols]
        self._history[:, :-1] = self._history[:, 1:].clone()
        self._history[:, -1] = obs
        for k, hist in self._frames.items():  # reading env.sensors.images renders this step's frames
            hist[:, :-1] = hist[:, 1:].clone()
            hist[:, -1] = env.sensors.images[k]
        if fresh.size:
            rows = torch.as_tensor(fresh, device=env.torch_device)
            self._history[rows] = obs[rows].unsqueeze(1).expand(-1, self._history.shape[1], -1)
            for hist in self._frames.values():
                hist[rows] = hist[rows, -1:].expand_as(hist[rows]).clone()
            self._cursor[fresh] = self._queue.shape[1]
        # only the rows asked for re-plan: in a coherent task those in this policy's phase (a row entering it is
        # reset, so the queues of the others are never read); inference for the rest was wasted work
        asked = as_rows(env_ids, env.num_envs)
        replan = asked[self._cursor[asked] >= self._queue.shape[1]]
        if replan.size:
            rows = torch.as_tensor(replan, device=env.torch_device)
            images = {k: hist[rows] for k, hist in self._frames.items()} if self._frames else None
            if self._sampler is None:  # a policy object of its own kind: its predict_action
                seen = {"images": images} if images else {}
                planned = self.policy.predict_action(self._history[rows], generator=self._generator, **seen)
            else:  # the noise predict_action would draw, then its sampling (from CUDA graphs on a GPU)
                noise = self.policy.initial_noise(len(replan), self._generator)
                planned = self._sampler(self._history[rows], images, noise)
            self._queue[rows] = planned.to(self._queue.device)
            self._cursor[replan] = 0
        idx = torch.as_tensor(np.minimum(self._cursor, self._queue.shape[1] - 1), device=env.torch_device)
        actions = self._queue[torch.arange(env.num_envs, device=env.torch_device), idx].contiguous()
        self._cursor += 1
        if self._act_cols is None:
            return actions
        out = env.current_action()
        out[:, self._act_cols] = actions
        return out


def checkpoint_agent(path: str | Path, device: str = "cpu", *, graphs: bool = True) -> BaseAgent:
    """A checkpoint's agent: a diffusion policy (``newton-lab train``) or a PPO actor (``newton-lab train-rl``), told
    apart by the checkpoint's format tag (``graphs``: the diffusion policy's sampling from CUDA graphs on a GPU)."""
    from .rl.agent import RLPolicyAgent, is_rl_checkpoint  # deferred: only a PPO checkpoint needs its agent

    if is_rl_checkpoint(path):
        return RLPolicyAgent.from_checkpoint(path, device=device)
    return PolicyAgent.from_checkpoint(path, device=device, graphs=graphs)
