"""Batched envs: ``make_env(task_id, ...)`` builds a ``NewtonEnv`` for a registered task."""

from __future__ import annotations

import inspect
from typing import Any


def make_env(
    task_id: str,
    num_envs: int = 1,
    device: str | None = None,
    seed: int | None = None,
    randomize: bool = False,
    task_options: dict[str, Any] | None = None,
    *,
    capture: bool = True,
):
    """Build the env of ``task_id`` with ``num_envs`` rows on ``device`` (Warp's default when ``None``).

    ``randomize`` turns on the task's reset randomisation (seeded per row by ``seed``);
    ``task_options`` are the task's own options (unknown keys raise with the valid ones).
    """
    from ..registry import lookup
    from .env import NewtonEnv

    entry = lookup(task_id)
    if not isinstance(num_envs, int) or isinstance(num_envs, bool) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    options = dict(task_options or {})
    factory = entry["cfg"]
    valid = [p for p in inspect.signature(factory).parameters]
    unknown = sorted(set(options) - set(valid))
    if unknown:
        raise ValueError(
            f"unknown task option(s) {unknown} for {task_id}; valid options: {valid if valid else 'none'}"
        )
    cfg = factory(**options)
    cfg.options = options
    return NewtonEnv(cfg, num_envs=num_envs, device=device, seed=seed, randomize=randomize, capture=capture)


__all__ = ["make_env"]
