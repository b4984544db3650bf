"""Task ids known without importing the task packages (importing them imports Warp and Newton, seconds).

``declared_task_ids()`` reads the ``id="..."`` keyword of every ``TaskSpec(...)`` / ``mimic_variant(...)``
call in the task packages' ``__init__.py`` with ``ast`` (nothing is executed); the command line checks a
``--task`` against it before any heavy import. ``declared_options()`` reads the ``TaskOption(...)``
declarations the same way, and which ids take which: the command line turns them into flags
(``--sorting-object``) and refuses an option a task does not take, or a value outside its choices, at once.
tests/test_cli.py checks both against the registry.
``did_you_mean`` is the one close-match helper of the project (``difflib``).
"""

from __future__ import annotations

import ast
import difflib
import functools
import importlib.util
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

DECLARING_CALLS = ("TaskSpec", "mimic_variant")
"""Calls whose literal ``id=`` keyword declares a task id."""


@dataclass(frozen=True)
class DeclaredOption:
    """A task option as its ``TaskOption(...)`` call spells it (literal values only)."""

    name: str
    doc: str = ""
    choices: tuple[str, ...] | None = None
    """Valid values when they are written as a literal tuple, else ``None`` (checked when the task is built)."""


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """`` (did you mean X?)`` for the closest of ``choices`` to ``word`` (``difflib``), else ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def _call_name(node: ast.Call) -> str:
    func = node.func
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")


def _ids_in(source: str) -> list[str]:
    ids = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and _call_name(node) in DECLARING_CALLS:
            ids += [
                kw.value.value
                for kw in node.keywords
                if kw.arg == "id" and isinstance(kw.value, ast.Constant) and isinstance(kw.value.value, str)
            ]
    return ids


OBS_MODE = DeclaredOption(
    name="obs_mode",
    choices=("state", "sensors"),
    doc="every task: state (every observation term the task declares) or sensors (what a real robot measures: "
    "proprioception and cameras, no object or target poses)",
)
"""The option every task takes (``TaskSpec.all_options``), listed after the task's own."""


def _task_inits() -> list[Path]:
    spec = importlib.util.find_spec("newton_lab.tasks")  # locates the package; does not execute it
    roots = [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    return [init for root in roots for init in sorted(root.glob("*/__init__.py"))]


@functools.cache
def declared_task_ids() -> tuple[str, ...]:
    """Every task id the task packages declare, sorted (read from source, no import of the tasks)."""
    return tuple(sorted({i for init in _task_inits() for i in _ids_in(init.read_text())}))


def _literal(node: ast.AST | None):
    try:
        return ast.literal_eval(node) if node is not None else None
    except ValueError:
        return None


def _option(call: ast.Call) -> DeclaredOption | None:
    kw = {k.arg: k.value for k in call.keywords}
    name = _literal(kw.get("name"))
    if not isinstance(name, str):
        return None
    choices = _literal(kw.get("choices"))
    doc = _literal(kw.get("doc"))
    return DeclaredOption(
        name, doc if isinstance(doc, str) else "", tuple(choices) if isinstance(choices, tuple | list) else None
    )


def _options_in(source: str) -> dict[str, tuple[DeclaredOption, ...]]:
    """Task id -> its options, for one task package's ``__init__`` source: ``TaskOption`` calls bound to names,
    ``TaskSpec(id=..., options=(NAME, ...))``, ``X = register(TaskSpec(...))`` and ``mimic_variant(X, id=...)``."""
    tree = ast.parse(source)
    named: dict[str, DeclaredOption] = {}
    spec_ids: dict[str, str] = {}  # variable -> task id of the TaskSpec it holds
    out: dict[str, tuple[DeclaredOption, ...]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and _call_name(node.value) == "TaskOption":
            if (opt := _option(node.value)) is not None:
                named.update({t.id: opt for t in node.targets if isinstance(t, ast.Name)})
    for node in ast.walk(tree):  # SPEC = register(TaskSpec(id=...)): the variable names that id
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and node.value.args:
            inner = node.value.args[0]
            if isinstance(inner, ast.Call) and _call_name(inner) == "TaskSpec":
                task_id = _literal({k.arg: k.value for k in inner.keywords}.get("id"))
                spec_ids.update({t.id: task_id for t in node.targets if isinstance(t, ast.Name)})
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and _call_name(n) in DECLARING_CALLS]
    for node in sorted(calls, key=lambda n: _call_name(n) == "mimic_variant"):  # a variant after its source
        kw = {k.arg: k.value for k in node.keywords}
        task_id = _literal(kw.get("id"))
        if not isinstance(task_id, str):
            continue
        if _call_name(node) == "mimic_variant":
            source_var = node.args[0].id if node.args and isinstance(node.args[0], ast.Name) else None
            out[task_id] = out.get(spec_ids.get(source_var, ""), ())
            continue
        opts = kw.get("options")
        elts = opts.elts if isinstance(opts, ast.Tuple | ast.List) else []
        found = (
            named.get(e.id) if isinstance(e, ast.Name) else _option(e) if isinstance(e, ast.Call) else None
            for e in elts
        )
        out[task_id] = tuple(o for o in found if o is not None)
    return out


@functools.cache
def declared_options() -> dict[str, tuple[DeclaredOption, ...]]:
    """Task id -> the options it takes, read from the task packages' source (no import of the tasks)."""
    out: dict[str, tuple[DeclaredOption, ...]] = {}
    for init in _task_inits():
        out.update(_options_in(init.read_text()))
    return {task_id: (*opts, OBS_MODE) for task_id, opts in out.items()}


def all_declared_options() -> dict[str, DeclaredOption]:
    """Every option name any task declares (first declaration's doc and choices)."""
    found: dict[str, DeclaredOption] = {}
    for opts in declared_options().values():
        for o in opts:
            found.setdefault(o.name, o)
    return found


def check_task_options(task_id: str, options: dict) -> None:
    """Refuse, in one line and before any import, an option ``task_id`` does not take or a value outside the
    option's literal choices."""
    declared = {o.name: o for o in declared_options().get(task_id, ())}
    for name, value in options.items():
        if name not in declared:
            flag = "--" + name.replace("_", "-")
            valid = ", ".join("--" + n.replace("_", "-") for n in declared) or "none"
            raise ValueError(f"{task_id} takes no option {flag} ({name}); its options: {valid}")
        choices = declared[name].choices
        if choices is not None and value is not None and value not in choices:
            raise ValueError(f"unknown {name} {value!r}{did_you_mean(value, choices)}; valid values: {list(choices)}")


def check_task_id(task_id: str) -> None:
    """Refuse an unknown ``task_id`` in one line (closest id suggested, every id listed), before the task
    packages are imported."""
    known = declared_task_ids()
    if known and task_id not in known:
        raise ValueError(
            f"unknown task id {task_id!r}{did_you_mean(task_id, known)}; valid ids: "
            f"{', '.join(known)} (see `newton-lab tasks`)"
        )


def _phases_in(package: Path) -> dict[str, tuple[tuple[str, str, str], ...]]:
    """Coherent task id -> its phases as (phase name, component task id, kind), for one task package: the
    ``TaskSpec(id=..., cfg=NAME)`` of its ``__init__`` and the literal ``phase("name", "task id", ...)`` calls in the
    body of the function ``NAME`` (any module of the package); the kind is a literal ``kind=`` or the name."""
    cfgs: dict[str, str] = {}  # cfg function name -> task id
    for node in ast.walk(ast.parse((package / "__init__.py").read_text())):
        if isinstance(node, ast.Call) and _call_name(node) == "TaskSpec":
            kw = {k.arg: k.value for k in node.keywords}
            task_id, cfg = _literal(kw.get("id")), kw.get("cfg")
            if isinstance(task_id, str) and isinstance(cfg, ast.Name):
                cfgs[cfg.id] = task_id
    out: dict[str, tuple[tuple[str, str, str], ...]] = {}
    for module in sorted(package.rglob("*.py")):
        for fn in ast.walk(ast.parse(module.read_text())):
            if not isinstance(fn, ast.FunctionDef) or fn.name not in cfgs:
                continue
            phases = tuple(
                (node.args[0].value, node.args[1].value, _literal_kind(node) or node.args[0].value)
                for node in ast.walk(fn)
                if isinstance(node, ast.Call)
                and _call_name(node) == "phase"
                and len(node.args) >= 2
                and all(isinstance(a, ast.Constant) and isinstance(a.value, str) for a in node.args[:2])
            )
            if phases:
                out[cfgs[fn.name]] = phases
    return out


def _literal_kind(call: ast.Call) -> str | None:
    kind = _literal({k.arg: k.value for k in call.keywords}.get("kind"))
    return kind if isinstance(kind, str) else None


@functools.cache
def _declared_phase_calls() -> dict[str, tuple[tuple[str, str, str], ...]]:
    out: dict[str, tuple[tuple[str, str, str], ...]] = {}
    for init in _task_inits():
        out.update(_phases_in(init.parent))
    return out


def declared_phases() -> dict[str, tuple[tuple[str, str], ...]]:
    """Coherent task id -> its phases, in order, as (phase name, component task id), read from the task packages'
    source (no import of the tasks); a task that is not coherent is absent. tests/test_cli.py checks it against
    the registry."""
    return {t: tuple((name, comp) for name, comp, _ in ph) for t, ph in _declared_phase_calls().items()}


def declared_phase_kinds() -> dict[str, dict[str, str]]:
    """Coherent task id -> its phase kinds (``PhaseCfg.kind``, else the name) -> component task id, from source."""
    return {t: {kind: comp for _, comp, kind in ph} for t, ph in _declared_phase_calls().items()}


@functools.cache
def declared_sources() -> dict[str, str]:
    """Mimic variant id -> the id of the task it is a variant of (``mimic_variant(SPEC, id=...)``), from source."""
    out: dict[str, str] = {}
    for init in _task_inits():
        tree = ast.parse(init.read_text())
        spec_ids: dict[str, str] = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and node.value.args:
                inner = node.value.args[0]
                if isinstance(inner, ast.Call) and _call_name(inner) == "TaskSpec":
                    task_id = _literal({k.arg: k.value for k in inner.keywords}.get("id"))
                    spec_ids.update({t.id: task_id for t in node.targets if isinstance(t, ast.Name)})
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and _call_name(node) == "mimic_variant" and node.args:
                task_id = _literal({k.arg: k.value for k in node.keywords}.get("id"))
                source = node.args[0].id if isinstance(node.args[0], ast.Name) else None
                if isinstance(task_id, str) and spec_ids.get(source):
                    out[task_id] = spec_ids[source]
    return out


@functools.cache
def declared_mimic_arms() -> dict[str, str]:
    """Task id -> the arm its Mimic variant segments (``MimicCfg(arm=...)``, default ``left``), for every task that
    has a variant, from source: a package's ``MimicCfg`` calls give its tasks' arm."""
    sources = set(declared_sources().values())
    out: dict[str, str] = {}
    for init in _task_inits():
        arms = [
            _literal({k.arg: k.value for k in node.keywords}.get("arm")) or "left"
            for module in sorted(init.parent.rglob("*.py"))
            for node in ast.walk(ast.parse(module.read_text()))
            if isinstance(node, ast.Call) and _call_name(node) == "MimicCfg"
        ]
        for task_id in set(_ids_in(init.read_text())) & sources:
            out[task_id] = arms[0] if arms else "left"
    return out
