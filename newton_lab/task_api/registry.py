"""Task registry: task ids -> typed, frozen ``TaskSpec``s.

Task packages register themselves (``register(TaskSpec(...))`` in ``tasks/<task>/__init__.py``); importing
``newton_lab.tasks`` registers every id, and ``newton_lab.envs`` does that import once, explicitly. The
registry itself imports no task.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from .catalog import OBS_MODE as _OBS_MODE_DECL, did_you_mean
from .cfg import TaskCfg
from .experts import Expert
from .mimic_cfg import MimicCfg
from .terms import resolve_cfg

DEFAULT_TASK_ID = "GalbotG1-PickCube-v0"


@dataclass(frozen=True, kw_only=True)
class TaskOption:
    """One option a task takes (``make_env(..., task_options={name: value})``)."""

    name: str
    choices: tuple[str, ...] | None = None
    """Valid values; ``None`` accepts any value."""
    default: Any = None
    doc: str = ""


@dataclass(frozen=True, kw_only=True)
class TaskSpec:
    """Everything the platform knows about a task id: how to build it, its options, its expert, its Mimic
    decomposition. Factories are callables taking the task options as keywords."""

    id: str
    cfg: Callable[..., TaskCfg]
    """Env configuration factory: ``cfg(**options) -> TaskCfg``."""
    description: str
    options: tuple[TaskOption, ...] = ()
    """Options schema; unknown keys or values outside ``choices`` are refused in one line."""
    expert: Callable[..., Expert] | None = None
    """Expert declaration factory: ``expert(**options)`` -> a motion plan, nav, joint-target or sequence
    expert (data; ``newton_lab.agents.agent_for_declaration`` turns it into an agent). Coherent tasks leave it
    ``None``: their expert runs the component experts phase by phase."""
    mimic: MimicCfg | None = None
    """Subtask decomposition for Mimic generation (Mimic variants only)."""
    source_task: str | None = None
    """The task whose demos a Mimic variant expands."""
    teleop: str | None = None
    """Teleop contract (``agents.teleop.contracts.CONTRACTS``: the joint groups an operator drives); ``None``:
    no teleop device drives this task."""

    @property
    def all_options(self) -> tuple[TaskOption, ...]:
        """The task's own options, then the ones every task takes (``obs_mode``)."""
        return (*self.options, *BUILTIN_OPTIONS)

    @property
    def option_names(self) -> list[str]:
        """Names of ``all_options``."""
        return [o.name for o in self.all_options]

    def check_options(self, options: Mapping[str, Any] | None) -> dict[str, Any]:
        """``options`` as a dict after checking keys and values against the schema (one-line errors)."""
        options = dict(options or {})
        unknown = sorted(set(options) - set(self.option_names))
        if unknown:
            hint = did_you_mean(unknown[0], self.option_names) if len(unknown) == 1 else ""
            raise ValueError(
                f"unknown task option(s) {unknown} for {self.id}{hint}; valid options: {self.option_names}"
            )
        for opt in self.all_options:
            value = options.get(opt.name)
            if value is not None and opt.choices is not None and value not in opt.choices:
                raise ValueError(
                    f"unknown {opt.name} {value!r}{did_you_mean(value, opt.choices)}; valid values: {list(opt.choices)}"
                )
        return options

    def choice_sets(self) -> list[dict[str, Any]]:
        """One options dict per combination of the values of the task's own options with choices (``[{}]`` when
        it has none): what a sweep over every variant of the task runs (e.g. each sorting object)."""
        sets: list[dict[str, Any]] = [{}]
        for opt in self.options:
            if opt.choices:
                sets = [{**s, opt.name: c} for s in sets for c in opt.choices]
        return sets

    def accepted(self, options: Mapping[str, Any] | None) -> dict[str, Any]:
        """The subset of ``options`` this task declares itself (a coherent task passes its options to every
        component; each takes the ones it knows; the built-in ``obs_mode`` is applied to the coherent task)."""
        own = {o.name for o in self.options}
        return {k: v for k, v in (options or {}).items() if k in own}

    def make_cfg(self, options: Mapping[str, Any] | None = None) -> TaskCfg:
        """The env configuration for ``options`` (checked): ``cfg.task_id`` is this spec's id, ``cfg.options``
        records the options, and every generic term is resolved against the scene (``resolve_cfg``)."""
        options = self.check_options(options)
        cfg = dataclasses.replace(self.cfg(**self._own(options)), task_id=self.id, options=options)
        if options.get(OBS_MODE.name, OBS_MODE.default) == "sensors":
            cfg = without_privileged(cfg)
        return resolve_cfg(cfg)

    def _own(self, options: dict[str, Any]) -> dict[str, Any]:
        """The options the task's own factories take (the built-in ones are the registry's)."""
        return {k: v for k, v in options.items() if k not in {o.name for o in BUILTIN_OPTIONS}}

    def make_expert(self, options: Mapping[str, Any] | None = None) -> Expert:
        """The expert declaration for ``options``; raises when the task declares none."""
        if self.expert is None:
            raise ValueError(
                f"task {self.id!r} declares no expert; pass an agent (e.g. a policy) or, for a "
                "coherent task, use TaskFlowAgent"
            )
        return self.expert(**self._own(self.check_options(options)))


OBS_MODE = TaskOption(name=_OBS_MODE_DECL.name, choices=_OBS_MODE_DECL.choices, default="state", doc=_OBS_MODE_DECL.doc)
"""The option every task takes: ``sensors`` drops the privileged observation terms (``ObsTermCfg.privileged``)."""
BUILTIN_OPTIONS = (OBS_MODE,)


def without_privileged(cfg: TaskCfg) -> TaskCfg:
    """``cfg`` observing only what a real robot measures: its privileged observation terms dropped."""
    return dataclasses.replace(cfg, observations={k: t for k, t in cfg.observations.items() if not t.privileged})


_REGISTRY: dict[str, TaskSpec] = {}


def register(spec: TaskSpec) -> TaskSpec:
    """Add ``spec``; an id registered twice raises."""
    if not isinstance(spec, TaskSpec):
        raise TypeError(f"register takes a TaskSpec, got {type(spec).__name__}")
    if spec.id in _REGISTRY:
        raise ValueError(f"task id {spec.id!r} is already registered; pick a new id or unregister it first")
    _REGISTRY[spec.id] = spec
    return spec


def unregister(task_id: str) -> None:
    """Remove ``task_id`` (tests registering throw-away tasks)."""
    _REGISTRY.pop(task_id, None)


def list_tasks() -> list[str]:
    """All registered task ids, sorted (empty until ``newton_lab.tasks`` is imported)."""
    return sorted(_REGISTRY)


def lookup(task_id: str) -> TaskSpec:
    """The spec of ``task_id``; unknown ids raise with the list of valid ones."""
    if task_id not in _REGISTRY:
        valid = ", ".join(sorted(_REGISTRY)) or "none (import newton_lab.tasks to register them)"
        raise ValueError(f"unknown task id {task_id!r}{did_you_mean(task_id, _REGISTRY)}; valid ids: {valid}")
    return _REGISTRY[task_id]


def mimic_variant(source: TaskSpec, *, id: str, mimic: MimicCfg) -> TaskSpec:
    """A Mimic generation variant of ``source``: the same scene, terms, randomisation and options, under its
    own id, with the subtask decomposition ``mimic``."""

    return TaskSpec(
        id=id,
        cfg=source.cfg,
        description=f"Mimic generation variant of {source.id}.",
        options=source.options,
        expert=source.expert,
        mimic=mimic,
        source_task=source.id,
    )


def mimic_variant_of(task_id: str) -> TaskSpec:
    """The registered Mimic variant whose source task is ``task_id``."""
    variants = {s.source_task: s for s in _REGISTRY.values() if s.mimic is not None}
    if task_id not in variants:
        raise ValueError(
            f"task {task_id!r} has no Mimic variant; tasks with one: {', '.join(sorted(variants)) or 'none'}"
        )
    return variants[task_id]
