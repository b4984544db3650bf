"""Task ids known without importing the task packages (importing them imports Warp and Newton, seconds).

``declared_task_ids()`` reads the ``id="..."`` keyword of every ``TaskSpec(...)`` / ``mimic_variant(...)``
call in the task packages' ``__init__.py`` with ``ast`` (nothing is executed); the command line checks a
``--task`` against it before any heavy import. tests/test_cli.py checks that it equals the registry.
``did_you_mean`` is the one close-match helper of the project (``difflib``).
"""

from __future__ import annotations

import ast
import difflib
import functools
import importlib.util
from collections.abc import Iterable
from pathlib import Path

DECLARING_CALLS = ("TaskSpec", "mimic_variant")
"""Calls whose literal ``id=`` keyword declares a task id."""


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
            ids += [kw.value.value for kw in node.keywords
                    if kw.arg == "id" and isinstance(kw.value, ast.Constant) and isinstance(kw.value.value, str)]
    return ids


@functools.cache
def declared_task_ids() -> tuple[str, ...]:
    """Every task id the task packages declare, sorted (read from source, no import of the tasks)."""
    spec = importlib.util.find_spec("newton_lab.tasks")  # locates the package; does not execute it
    roots = [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    ids = [i for root in roots for init in sorted(root.glob("*/__init__.py")) for i in _ids_in(init.read_text())]
    return tuple(sorted(set(ids)))


def check_task_id(task_id: str) -> None:
    """Refuse an unknown ``task_id`` in one line (closest id suggested, every id listed), before the task
    packages are imported."""
    known = declared_task_ids()
    if known and task_id not in known:
        raise ValueError(f"unknown task id {task_id!r}{did_you_mean(task_id, known)}; valid ids: "
                         f"{', '.join(known)} (see `newton-lab tasks`)")
