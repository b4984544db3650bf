"""The agent contract, and the per-row episode bookkeeping agents share.

``BaseAgent`` is a template: ``act`` calls ``fresh_rows(env, env_ids)``, which binds the agent to a new env once
(``bind`` -> the subclass's ``setup(env)`` hook, then a fresh episode tracker) and returns the rows that started an
episode since the agent last looked; ``reset`` forgets rows. ``collect`` / ``evaluate`` call ``act``, ``reset``,
``done``, ``holding`` and read ``done_reason``: every agent has them from here.
"""

from __future__ import annotations

import numpy as np
import torch


class BaseAgent:
    """``act(env)`` returns a full (num_envs, action_dim) float32 action tensor on the env's device;
    ``reset(env_ids)`` clears per-row state. Agents never step, build or reset the env."""

    done_reason = "agent_done"
    """The termination reason a rollout records for an episode it ended because ``done`` held (with
    ``end_when_agent_done``); a teleop operator's is ``user_exit``."""
    bound_env = None
    """The env the agent holds per-row state for (``None`` before ``bind``)."""
    _tracker: EpisodeTracker | None = None

    def act(self, env, env_ids=None) -> torch.Tensor:  # pragma: no cover - interface
        raise NotImplementedError

    def bind(self, env) -> None:
        """Hold per-row state for ``env``: the subclass's ``setup(env)`` (its checks, one-line errors, and
        buffers), then a fresh episode tracker. Once per env; calling it again for the bound env does nothing."""
        if self.bound_env is env:
            return
        self.setup(env)
        self._tracker = EpisodeTracker(env.num_envs)
        self.bound_env = env

    def setup(self, env) -> None:
        """Hook of ``bind``: check ``env`` against the agent and allocate its per-row state."""

    def fresh_rows(self, env, env_ids=None) -> np.ndarray:
        """Rows (within ``env_ids``) that started an episode, or were ``reset``, since the agent last looked;
        binds to ``env`` first when it is new."""
        self.bind(env)
        return self._tracker.fresh_rows(env, env_ids)

    def reset(self, env_ids=None) -> None:
        """Forget per-row state of ``env_ids`` (all rows when ``None``): they start fresh at the next ``act``."""
        if self._tracker is not None:
            self._tracker.forget(env_ids)

    def done(self, env) -> torch.Tensor:
        """(num_envs,) bool: the agent has nothing more to do for a row (not an episode boundary)."""
        return torch.zeros(env.num_envs, dtype=torch.bool, device=env.torch_device)

    def holding(self) -> np.ndarray | None:
        """Rows (numpy bool) whose last action held while the agent prepared them (a planner waiting for its plan),
        or ``None``: a rollout starts such a row's episode over once the agent moves it."""
        return None


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
        episode = env.buffers.episode_count.cpu().numpy()
        rows = np.nonzero(episode != self.seen)[0]
        if env_ids is not None:
            rows = np.intersect1d(rows, as_rows(env_ids, len(self.seen)))
        self.seen[rows] = episode[rows]
        return rows
