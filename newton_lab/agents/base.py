"""The agent contract."""

from __future__ import annotations

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
