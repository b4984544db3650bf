"""Coherent long-horizon tasks from component tasks: ``coherent_task(..., phases=task_sequence(phase(...)))``.

Each phase names a registered component task. The coherent task runs them back to back inside one
episode: phase is a per-row device int, the component's success predicate advances only that row (inside
the fused task kernel), the last phase's success is episode success, and a component's failure terms end
the episode while the row is in that phase. Nothing is rebuilt, loaded or reset between phases.

The scene, posture, reset events and rewards come from the first phase; every component must share that
world (same entity names and order, so predicates address the same slots). The action space is the union of
the phases' action terms in first-seen order (or an explicit ``actions`` list); a phase commands only its
``terms`` groups, the others hold (position targets keep their value, wheel/base velocities go to zero).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from .cfg import ActionTermCfg, PhaseCfg, TaskCfg, TerminationTermCfg
from .physics import merged as merged_physics
from .registry import lookup


def phase(
    name: str,
    task_id: str,
    *,
    terms: tuple[str, ...],
    fixed_base: bool = False,
    kind: str | None = None,
    target_option: str | None = None,
) -> PhaseCfg:
    """A phase running component ``task_id`` that commands the joint groups ``terms`` (e.g. ``("base",)``);
    ``kind`` and ``target_option`` as ``PhaseCfg`` has them."""
    return PhaseCfg(
        name=name,
        task_id=task_id,
        action_groups=tuple(terms),
        fixed_base=fixed_base,
        kind=kind,
        target_option=target_option,
    )


def task_sequence(*phases: PhaseCfg) -> tuple[PhaseCfg, ...]:
    """Phases in execution order (names unique)."""
    names = [p.name for p in phases]
    if len(set(names)) != len(names) or not phases:
        raise ValueError(f"task_sequence needs at least one phase and unique names, got {names}")
    return tuple(phases)


TARGET_SEPARATOR = "/"
"""Joins a phase kind and a value of its target option into the name of a per-target policy (``pick/red_cube``)."""


def target_values(phase: PhaseCfg) -> tuple[str, ...]:
    """The values of ``phase``'s per-row target (``PhaseCfg.target_option``), in the order of its one-hot (the
    component's declared choices); ``()`` for a phase without one."""
    if not phase.target_option:
        return ()
    declared = {o.name: o.choices for o in lookup(phase.task_id).options}
    return tuple(declared.get(phase.target_option) or ())


def target_choices(cfg: TaskCfg, kind: str) -> tuple[str, tuple[str, ...]]:
    """The target option of a coherent task's phase ``kind`` and its values (``target_values``); one line when the
    kind has no per-row target."""
    ix = cfg.phase_kinds.get(kind)
    if ix is None:
        raise ValueError(f"{cfg.task_id} has no phase kind {kind!r}; its kinds: {', '.join(cfg.phase_kinds)}")
    ph = cfg.phases[ix[0]]
    values = target_values(ph)
    if not values:
        with_target = [k for k, i in cfg.phase_kinds.items() if cfg.phases[i[0]].target_option]
        raise ValueError(
            f"phase kind {kind!r} of {cfg.task_id} acts on no per-row target, so it has no policy per target; "
            f"kinds with one: {', '.join(with_target) or 'none'}"
        )
    return ph.target_option, values


def per_target_names(cfg: TaskCfg, kinds) -> list[str]:
    """``kind/value`` for every value of each of ``kinds``' target option (``target_choices``)."""
    return [f"{kind}{TARGET_SEPARATOR}{value}" for kind in kinds for value in target_choices(cfg, kind)[1]]


def _component(task_id: str, options: dict[str, Any]) -> TaskCfg:
    spec_ = lookup(task_id)
    return dataclasses.replace(spec_.cfg(**spec_.accepted(options)), task_id=task_id)


def coherent_task(
    *,
    phases: tuple[PhaseCfg, ...],
    options: dict[str, Any] | None = None,
    actions: list[ActionTermCfg] | None = None,
    terminations: dict[str, TerminationTermCfg] | None = None,
    **overrides: Any,
) -> TaskCfg:
    """Build a coherent task from its component phases (its id comes from the ``TaskSpec`` registering it).

    Args:
        phases: from ``task_sequence``.
        options: task options passed to every component factory that accepts them (e.g. ``sorting_object``).
        actions: explicit action terms (order = columns); default: union of the components' terms.
        terminations: extra failure terms applying in every phase.
        overrides: ``TaskCfg`` fields replacing the first phase's (e.g. ``episode_length_s``).
    """
    options = dict(options or {})
    parts = [_component(p.task_id, options) for p in phases]
    first = parts[0]
    names = [e.name for e in first.entities]
    for p, cfg in zip(phases, parts):
        other = [e.name for e in cfg.entities]
        if other != names:
            raise ValueError(
                f"phase {p.name!r} ({p.task_id}) has objects {other} but the coherent task's world has "
                f"{names}; components of a coherent task must share one world"
            )
        if tuple(cfg.arm_home) != tuple(first.arm_home) or cfg.arm != first.arm:
            raise ValueError(f"phase {p.name!r} ({p.task_id}) uses another arm or arm reference posture")
        if cfg.robot != first.robot:
            raise ValueError(
                f"phase {p.name!r} ({p.task_id}) runs robot {cfg.robot!r} but the coherent task's first "
                f"phase runs {first.robot!r}; components of a coherent task share one robot"
            )

    if actions is None:
        actions = _union_by_name(cfg.actions for cfg in parts)
    groups = {t.group for t in actions}
    for p in phases:
        missing = sorted(set(p.action_groups or ()) - groups)
        if missing:
            raise ValueError(
                f"phase {p.name!r} commands {missing} but the coherent task's action terms have groups {sorted(groups)}"
            )

    observations = _union_of_dicts(cfg.observations for cfg in parts)  # widths are derived by the env
    terms: dict[str, TerminationTermCfg] = {}
    for i, cfg in enumerate(parts):
        for name, term in cfg.terminations.items():
            key = name if name not in terms else f"{phases[i].name}_{name}"
            terms[key] = dataclasses.replace(term, phase=i)
    terms.update(terminations or {})
    signals = _union_of_dicts(cfg.signals for cfg in parts)

    cfg = dataclasses.replace(
        first,
        task_id="",
        actions=list(actions),
        observations=observations,
        phase_success=[c.phase_success[-1] for c in parts],
        terminations=terms,
        phases=list(phases),
        signals=signals,
        hold_slots=max(c.hold_slots for c in parts),
        command_dim=max(c.command_dim for c in parts),
        fixed_base=False,
        physics=merged_physics([c.physics for c in parts]),
        terminate_on_success=True,
        scenario=None,
        options=options,
    )
    return dataclasses.replace(cfg, **overrides) if overrides else cfg


def _union_of_dicts(term_dicts) -> dict:
    """Terms of every dict, first occurrence of each name kept, in first-seen order."""
    out: dict[str, Any] = {}
    for terms in term_dicts:
        for name, term in terms.items():
            out.setdefault(name, term)
    return out


def _union_by_name(term_lists) -> list:
    """Terms of every list, first occurrence of each name kept, in first-seen order."""
    out: dict[str, Any] = {}
    for terms in term_lists:
        for term in terms:
            out.setdefault(term.name, term)
    return list(out.values())
