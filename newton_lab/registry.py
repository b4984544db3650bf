"""Task registry: task ids -> config factories. Tasks register themselves when
``newton_lab.tasks`` is imported (``make_env`` does that on first use)."""

from __future__ import annotations

import importlib
import inspect
from typing import Any, Callable

_REGISTRY: dict[str, dict[str, Any]] = {}
DEFAULT_TASK_ID = "GalbotG1-PickCube-v0"


def register(task_id: str, *, cfg: Callable[..., Any], motion_plan: str | None = None, **metadata: Any) -> None:
    """Register ``task_id``; ``cfg(**task_options)`` returns its ``TaskCfg``; ``motion_plan`` names the
    expert plan (``module:function``) the planner agent uses."""
    if task_id in _REGISTRY:
        raise ValueError(f"task id {task_id!r} is already registered; pick a new id or unregister it first")
    _REGISTRY[task_id] = {"cfg": cfg, "motion_plan": motion_plan, **metadata}


def _ensure_tasks_imported() -> None:
    if not _REGISTRY:
        importlib.import_module("newton_lab.tasks")


def list_tasks() -> list[str]:
    """All registered task ids, sorted."""
    _ensure_tasks_imported()
    return sorted(_REGISTRY)


def lookup(task_id: str) -> dict[str, Any]:
    """The registry entry of ``task_id``; unknown ids raise with the list of valid ones."""
    _ensure_tasks_imported()
    if task_id not in _REGISTRY:
        raise ValueError(f"unknown task id {task_id!r}; valid ids: {', '.join(sorted(_REGISTRY))}")
    return _REGISTRY[task_id]


def call_with_options(factory: Callable[..., Any], options: dict[str, Any] | None) -> Any:
    """Call ``factory`` with the task options it accepts (coherent tasks pass theirs to every component)."""
    accepted = inspect.signature(factory).parameters
    return factory(**{k: v for k, v in (options or {}).items() if k in accepted})


def resolve(ref: str) -> Any:
    """The object named by ``module:attribute``."""
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)
