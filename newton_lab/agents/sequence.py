"""SequenceAgent: ordered steps per row, each an agent with a done predicate; rows advance independently."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from .base import BaseAgent, as_rows


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
