"""Input checks of the env's public calls: one-line ``ValueError`` messages that name the problem and the fix."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ..task_api.registry import lookup


def check_actions(
    actions, *, num_envs: int, action_dim: int, device: torch.device, columns: Sequence[str], finite: bool = True
) -> torch.Tensor:
    """``actions`` if it is a finite float32 ``(num_envs, action_dim)`` tensor on ``device``; raises otherwise
    (``columns``: the action column names, quoted when the shape is wrong). The finiteness check reads the
    tensor on the host (one sync per call); ``finite=False`` leaves it to the caller."""
    if not isinstance(actions, torch.Tensor):
        raise ValueError(
            f"actions must be a torch.Tensor, got {type(actions).__name__}; "
            f"use torch.as_tensor(actions, dtype=torch.float32, device='{device}')"
        )
    expected = (num_envs, action_dim)
    if tuple(actions.shape) != expected:
        raise ValueError(
            f"actions must have shape (num_envs, action_dim) = {expected}, got {tuple(actions.shape)}; "
            f"columns are {list(columns)}"
        )
    if actions.dtype != torch.float32:
        raise ValueError(f"actions must be torch.float32, got {actions.dtype}; convert with actions.float()")
    if actions.device != device:
        raise ValueError(
            f"actions are on {actions.device} but the env runs on {device}; move them with actions.to('{device}')"
        )
    if finite and not bool(torch.isfinite(actions).all()):
        rows = torch.nonzero(~torch.isfinite(actions).all(dim=1)).flatten().tolist()
        raise ValueError(f"actions contain NaN or inf in rows {rows}; check the agent's output before stepping")
    return actions


def row_mask(env_ids, num_envs: int) -> np.ndarray:
    """(num_envs,) bool mask of the rows ``env_ids`` names (every row when ``None``); raises on boolean or
    floating ids and on ids outside ``[0, num_envs)``."""
    mask = np.zeros(num_envs, dtype=bool)
    if env_ids is None:
        mask[:] = True
        return mask
    try:
        given = torch.as_tensor(env_ids).cpu()
    except (TypeError, ValueError, RuntimeError):
        raise ValueError(
            f"env_ids must be None (every row) or integer row indices (a list, numpy array or tensor), "
            f"got {type(env_ids).__name__} {str(env_ids)[:60]}"
        ) from None
    if given.numel() and (given.dtype.is_floating_point or given.dtype.is_complex or given.dtype == torch.bool):
        raise ValueError(
            f"env_ids must be integer row indices, got dtype {given.dtype}; pass e.g. "
            f"torch.nonzero(mask).flatten() for a boolean mask"
        )
    ids = given.numpy().astype(np.int64).reshape(-1)
    if ids.size and (ids.min() < 0 or ids.max() >= num_envs):
        raise ValueError(f"env_ids must lie in [0, {num_envs}), got {ids.tolist()}")
    mask[ids] = True
    return mask


SEED_RANGE = (0, 2**31 - 1)
"""Seeds the env takes: Warp's reset kernels take a 32-bit seed, numpy no negative one, and HDF5 stores it as an
integer attribute (a larger Python int failed there, after the dataset file was made)."""


def check_seed(seed) -> int:
    """``seed`` as an int in ``SEED_RANGE``, or a one-line ``ValueError``."""
    lo, hi = SEED_RANGE
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not lo <= int(seed) <= hi:
        raise ValueError(f"seed must be an integer in [{lo}, {hi}], got {seed!r}")
    return int(seed)


AGENT_HOOKS = ("act", "reset", "done", "holding")
"""The calls a rollout makes on its agent (``newton_lab.agents.BaseAgent`` has them all, with ``done_reason``)."""


def check_agent(agent) -> None:
    """``agent`` has the rollout's hooks (``AGENT_HOOKS`` and ``done_reason``): a ``BaseAgent``."""
    missing = [h for h in AGENT_HOOKS if not callable(getattr(agent, h, None))]
    if missing or not isinstance(getattr(agent, "done_reason", None), str):
        raise ValueError(
            f"agent {type(agent).__name__} lacks {missing or ['done_reason']}; subclass "
            f"newton_lab.agents.BaseAgent (e.g. newton_lab.agents.expert_agent(env))"
        )


def check_counts(*, episodes, max_steps) -> None:
    """A rollout's ``episodes`` and ``max_steps`` are integers >= 1."""
    if not isinstance(episodes, int) or isinstance(episodes, bool) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if not isinstance(max_steps, int) or max_steps < 1:
        raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")


def check_collect(num_envs: int, *, agent, path, episodes, save_end_scenario) -> None:
    """``collect``'s inputs: an agent, a dataset path, and a scenario file to write only for one row and episode."""
    check_agent(agent)
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise ValueError(f"path must name the dataset to write (.hdf5, .h5 or .zarr), got {path!r}")
    if save_end_scenario is not None:
        if num_envs != 1 or episodes != 1:
            raise ValueError(f"save_end_scenario needs num_envs=1 and episodes=1, got {num_envs} and {episodes}")
        if Path(save_end_scenario).exists():
            raise FileExistsError(f"scenario file {save_end_scenario} already exists; choose a new path")


def option_defaults(task_id: str) -> dict[str, Any]:
    """The defaults of the options ``task_id`` takes (an appended dataset compares the options a run left unset)."""
    try:
        return {o.name: o.default for o in lookup(task_id).all_options}
    except (KeyError, ValueError):  # an env of a task the registry does not hold (built from a cfg)
        return {}
