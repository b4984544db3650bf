"""The agent contract, and the per-row episode bookkeeping agents share."""

from __future__ import annotations

import numpy as np
import torch


class BaseAgent:
    """``act(env)`` returns a full (num_envs, action_dim) float32 action tensor on the env's device;
    ``reset(env_ids)`` clears per-row state. Agents never step, build or reset the env."""

    def act(self, env, env_ids=None) -> torch.Tensor:  # pragma: no cover - interface
        raise NotImplementedError

    def reset(self, env_ids=None) -> None:
        """Forget per-row state of ``env_ids`` (all rows when ``None``)."""

    def done(self, env) -> torch.Tensor:
        """(num_envs,) bool: the agent has nothing more to do for a row (not an episode boundary)."""
        return torch.zeros(env.num_envs, dtype=torch.bool, device=env.torch_device)


class ZeroAgent(BaseAgent):
    """Holds every commanded joint at its current drive target."""

    def act(self, env, env_ids=None) -> torch.Tensor:
        return env.current_action()


def as_rows(env_ids, num_envs: int) -> np.ndarray:
    """``env_ids`` (None = all rows, or any index sequence / tensor) as a 1-D int64 numpy array."""
    if env_ids is None:
        return np.arange(num_envs)
    return np.asarray(torch.as_tensor(env_ids).cpu(), dtype=np.int64).reshape(-1)


class EpisodeTracker:
    """Which rows started a new episode (or were ``forget``-ed) since the agent last looked."""

    def __init__(self, num_envs: int):
        self.seen = np.full(num_envs, -1, dtype=np.int64)

    def forget(self, env_ids=None) -> None:
        self.seen[as_rows(env_ids, len(self.seen))] = -1

    def fresh_rows(self, env, env_ids=None) -> np.ndarray:
        """Rows (restricted to ``env_ids``) needing a fresh start; marks them seen."""
        episode = env.episode_count.cpu().numpy()
        rows = np.nonzero(episode != self.seen)[0]
        if env_ids is not None:
            rows = np.intersect1d(rows, as_rows(env_ids, len(self.seen)))
        self.seen[rows] = episode[rows]
        return rows
