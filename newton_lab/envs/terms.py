"""A task's declared terms -> the env's observation layout and its fused kernels (``newton_lab.kernels.fuse``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..kernels import fuse
from ..task_api.cfg import BUILTIN_TERMINATION_REASONS, DERIVED_SIZES, TaskCfg


def observation_layout(cfg: TaskCfg, derived: dict[str, int]) -> dict[str, slice]:
    """Column slice of every observation term, in declaration order. ``derived`` gives the widths the env
    knows (``action_dim``, ``robot_coords``, ``arm_joints``)."""
    layout, col = {}, 0
    for name, term in cfg.observations.items():
        size = term.size
        if isinstance(size, str):
            if size not in derived:
                raise ValueError(
                    f"observation {name!r} of {cfg.task_id} has size {size!r}; use an int or one of "
                    f"{list(DERIVED_SIZES)}"
                )
            size = derived[size]
        layout[name] = slice(col, col + int(size))
        col += int(size)
    return layout


@dataclass(frozen=True)
class TaskKernels:
    """The fused kernels of one task: step (phase, success, terminations, reward), observation, subtask
    signals (``None`` without signals) and masked reset."""

    task: Any
    observe: Any
    signals: Any
    reset: Any


def build_task_kernels(cfg: TaskCfg, obs_layout: dict[str, slice]) -> TaskKernels:
    """Fuse ``cfg``'s terms into its kernels."""
    clash = sorted(set(cfg.terminations) & set(BUILTIN_TERMINATION_REASONS))
    if clash:
        raise ValueError(
            f"{cfg.task_id}: termination terms may not be named {clash}; those names are the env's "
            f"own reasons {list(BUILTIN_TERMINATION_REASONS)}; rename the terms"
        )
    return TaskKernels(
        task=fuse.build_task_kernel(
            phase_success=cfg.phase_success,
            terminations=[(t.func, t.phase) for t in cfg.terminations.values()],
            rewards=[(t.func, t.weight) for t in cfg.rewards.values()],
            terminate_on_success=cfg.terminate_on_success,
        ),
        observe=fuse.build_observation_kernel(
            [(term.func, obs_layout[name].start) for name, term in cfg.observations.items()]
        ),
        signals=fuse.build_signal_kernel([t.func for t in cfg.signals.values()]) if cfg.signals else None,
        reset=fuse.build_reset_kernel([t.func for t in cfg.events.values()]),
    )
