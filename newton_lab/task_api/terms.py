"""Parametrised task terms: generic terms that name their scene objects and constants, compiled into Warp.

A term factory is a Python function returning a ``@wp.func``; ``@term_factory`` marks which of its keyword
parameters name scene objects. A task lists it with parameters by name, as mjlab's ``params``::

    TerminationTermCfg(func=common.dropped, params={"entity": "cube", "below_z": 0.05})
    phase_success=[common.lifted(entity="cube", min_z=0.225, hold_steps=5)]   # a bound Term

When a cfg is made (``TaskSpec.make_cfg``), ``resolve_cfg`` turns every term into a plain ``@wp.func``: object names
become their slots in the task's entity list, and the factory bakes slots and constants into the generated function
as compile-time constants (Warp closures), so the fused task kernel is what a hand-written term would give. The env
takes a cfg through ``resolved_cfg``, which resolves terms replaced after ``make_cfg`` and refuses an unnamed cfg.
Parameters may hold other terms (a reward stage's predicate, ``held(...)``'s condition): they are resolved
first. A factory declared with ``hold_counter=True`` also gets ``hold_slot``, a per-row counter index of its
own (``ctx.hold``), so no task keeps slot numbers by hand.

The same factory with the same parameters resolves to the same function (one compile, one counter).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from .catalog import did_you_mean


class TermFactory:
    """A generic term: ``factory(**params) -> @wp.func``. Call it with parameters to get a bound ``Term``.
    Compared and hashed by identity, like the function it wraps."""

    def __init__(self, factory: Callable[..., Any], entities: tuple[str, ...] = (), hold_counter: bool = False):
        self.factory = factory
        self.entities = tuple(entities)
        """Parameters that name scene objects (a name, or a tuple of names): resolved to slots [int]."""
        self.hold_counter = bool(hold_counter)
        """The generated function keeps a consecutive-step counter: it gets a ``hold_slot`` of its own."""
        functools.update_wrapper(self, factory, updated=())

    def __call__(self, **params: Any) -> Term:
        return Term(self, _freeze(params))

    def __repr__(self) -> str:
        return f"<term factory {self.__name__}>"


def term_factory(*, entities: tuple[str, ...] = (), hold_counter: bool = False):
    """Mark ``factory(**params) -> @wp.func`` as a parametrised term (see the module docstring)."""

    def wrap(factory: Callable[..., Any]) -> TermFactory:
        return TermFactory(factory, tuple(entities), hold_counter)

    return wrap


@dataclass(frozen=True)
class Term:
    """A term factory with its parameters, not yet resolved (hashable: parameters are frozen)."""

    factory: TermFactory
    params: tuple[tuple[str, Any], ...]

    @property
    def name(self) -> str:
        return self.factory.__name__


def bind(func: Any, params: Mapping[str, Any] | None = None) -> Any:
    """``func`` with ``params`` as one term: a ``Term`` for a factory, else ``func`` itself (a plain
    ``@wp.func`` takes no parameters)."""
    if isinstance(func, Term):
        if params:
            raise ValueError(f"term {func.name} is already bound; give its parameters once")
        return func
    if isinstance(func, TermFactory):
        return func(**dict(params or {}))
    if params:
        raise ValueError(
            f"params {sorted(params)} given to {getattr(func, '__name__', func)!r}, which is a plain "
            "@wp.func; declare it with @term_factory to take parameters"
        )
    return func


def _freeze(params: Mapping[str, Any]) -> tuple[tuple[str, Any], ...]:
    def frozen(v: Any) -> Any:
        if isinstance(v, list | tuple):
            return tuple(frozen(x) for x in v)
        if isinstance(v, Mapping):
            return tuple(sorted((k, frozen(x)) for k, x in v.items()))
        return v

    items = tuple(sorted((k, frozen(v)) for k, v in params.items()))
    try:
        hash(items)
    except TypeError as exc:
        raise ValueError(
            f"term parameters must be names, numbers, tuples or terms; got {dict(params)} ({exc})"
        ) from None
    return items


class TermResolver:
    """Resolves terms for one scene: object names -> slots, nested terms first, one function per distinct term,
    one hold counter per distinct counting term."""

    def __init__(self, entity_names: tuple[str, ...] | list[str], *, task: str = "task"):
        self.entity_names = tuple(entity_names)
        self.task = task
        self.hold_slots = 0
        """Hold counters handed out so far."""
        self._done: dict[Term, Any] = {}

    def slot(self, name: Any, param: str, term: str) -> int:
        if isinstance(name, int) and not isinstance(name, bool):
            raise ValueError(
                f"{self.task}: term {term} parameter {param}={name}: name the object (one of "
                f"{list(self.entity_names)}), not its slot number"
            )
        if name not in self.entity_names:
            raise ValueError(
                f"{self.task}: term {term} parameter {param}={name!r} names no scene object"
                f"{did_you_mean(name, self.entity_names)}; objects: {list(self.entity_names)}"
            )
        return self.entity_names.index(name)

    def __call__(self, func: Any) -> Any:
        """The ``@wp.func`` of ``func`` (a ``Term``, or an already plain function, returned as is)."""
        if isinstance(func, TermFactory):
            func = func()
        if not isinstance(func, Term):
            return func
        if func not in self._done:
            self._done[func] = self._build(func)
        return self._done[func]

    def _value(self, v: Any) -> Any:
        if isinstance(v, Term | TermFactory):
            return self(v)
        if isinstance(v, tuple):
            return tuple(self._value(x) for x in v)
        return v

    def _build(self, term: Term) -> Any:
        f = term.factory
        kwargs = {}
        for key, value in term.params:
            if key in f.entities:
                kwargs[key] = (
                    tuple(self.slot(n, key, term.name) for n in value)
                    if isinstance(value, tuple)
                    else self.slot(value, key, term.name)
                )
            else:
                kwargs[key] = self._value(value)
        if f.hold_counter:
            kwargs["hold_slot"] = self.hold_slots
            self.hold_slots += 1
        try:
            return f.factory(**kwargs)
        except TypeError as exc:
            raise ValueError(f"{self.task}: term {term.name} parameters {sorted(kwargs)}: {exc}") from None


TERM_FIELDS = ("observations", "terminations", "rewards", "signals", "events")
"""``TaskCfg`` fields whose values are ``TermCfg``s."""


def unresolved_terms(cfg) -> list[str]:
    """``field.name`` of every term of ``cfg`` still a generic term (a ``Term`` or ``TermFactory``, not yet a
    ``@wp.func``): a cfg from ``TaskSpec.cfg()``, or a resolved one whose terms were replaced afterwards (StackCube's
    ``reference_rewards()``)."""
    generic = (Term, TermFactory)
    out = [f"phase_success[{i}]" for i, f in enumerate(cfg.phase_success) if isinstance(f, generic)]
    for field in TERM_FIELDS:
        out += [f"{field}.{k}" for k, t in getattr(cfg, field).items() if isinstance(t.func, generic) or t.params]
    return out


def resolve_cfg(cfg, *, first_hold_slot: int = 0):
    """``cfg`` with every term a plain ``@wp.func`` (entity names -> slots) and ``hold_slots`` covering the
    counters the terms asked for. A resolved cfg resolves to itself. ``first_hold_slot``: the first counter handed
    out (``cfg.hold_slots`` when some terms were resolved before and keep their counters)."""
    resolver = TermResolver([e.name for e in cfg.entities], task=cfg.task_id or "task")
    resolver.hold_slots = first_hold_slot
    fields: dict[str, Any] = {"phase_success": [resolver(bind(f)) for f in cfg.phase_success]}
    for name in TERM_FIELDS:
        fields[name] = {
            k: dataclasses.replace(t, func=resolver(bind(t.func, t.params)), params={})
            for k, t in getattr(cfg, name).items()
        }
    fields["hold_slots"] = max(cfg.hold_slots, resolver.hold_slots)
    return dataclasses.replace(cfg, **fields)


def resolved_cfg(cfg):
    """The cfg an env is built from: ``cfg`` with its generic terms resolved, or a one-line ``ValueError``: a cfg
    that names no task (``TaskSpec.cfg()``) is refused; one whose terms were replaced after ``make_cfg`` (StackCube's
    ``reference_rewards()``) resolves the new terms here, each ``held`` counter a new one."""
    if not getattr(cfg, "task_id", None):
        raise ValueError(
            "this TaskCfg names no task: TaskSpec.cfg() neither names it nor resolves its generic "
            "terms; build the env with make_env(task_id), or from TaskSpec.make_cfg(options)"
        )
    if not unresolved_terms(cfg):
        return cfg
    return resolve_cfg(cfg, first_hold_slot=cfg.hold_slots)
