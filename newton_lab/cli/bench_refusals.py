"""``newton-lab bench-refusals``: every case of the bad-input table (``refusal_cases.CASES``) run as a user meets it,
a fresh ``newton-lab`` process each, timed from its start to its exit (interpreter start, imports and the check
included), in a working folder that holds the files the cases name.

The figures: wall seconds (median, 95th percentile, max) and CPU seconds of each process, and per case its exit
status, whether it printed exactly one line, whether that line holds the table's words, and whether the folder was
left as it was. The record (kind ``bench-refusals``) feeds the results page's "Refusals" table.
"""

from __future__ import annotations

import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from ..commands.refusal_cases import CASES, make_inputs

SLOWEST = 5
"""How many of the slowest cases the record names."""


def newton_lab_command() -> list[str]:
    """How a user starts ``newton-lab`` here: the console script beside this Python, else
    ``python -m newton_lab.cli``."""
    script = shutil.which("newton-lab", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "newton_lab.cli"]


def _tree(root: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in sorted(root.rglob("*"))}


def _cpu_of_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def time_case(command: list[str], argv: str, words: str, root: Path) -> dict[str, Any]:
    """One case in a fresh process in ``root``: its exit status, seconds and whether it was refused as the table
    says (exit status 2, one line holding ``words``, ``root`` unchanged)."""
    before = _tree(root)
    cpu, start = _cpu_of_children(), time.perf_counter()
    out = subprocess.run([*command, *argv.split()], cwd=root, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - start
    one_line = out.stderr.count("\n") == 1
    unchanged = _tree(root) == before
    return {
        "argv": argv,
        "exit": out.returncode,
        "one_line": one_line,
        "words": words in out.stderr,
        "unchanged": unchanged,
        "refused": out.returncode == 2 and one_line and words in out.stderr and unchanged,
        "wall_s": round(wall, 3),
        "cpu_s": round(_cpu_of_children() - cpu, 3),
    }


def _spread(values: list[float]) -> dict[str, float]:
    ordered = sorted(values)
    p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
    return {"median": round(statistics.median(ordered), 3), "p95": round(p95, 3), "max": round(ordered[-1], 3)}


def bench_refusals(only: list[str] | None = None, on_case=None) -> dict[str, Any]:
    """Time every case (``only``: those of these commands, e.g. ``["split", "view"]``); ``on_case(result)`` is
    called after each. The results of the record: counts, wall / CPU spread, the slowest cases, every case."""
    cases = [(a, w) for a, w in CASES if not only or a.split()[0] in only]
    if not cases:
        raise ValueError(
            f"--only {' '.join(only or [])}: no case of the bad-input table runs those commands; its "
            f"commands: {', '.join(sorted({a.split()[0] for a, _ in CASES}))}"
        )
    command = newton_lab_command()
    results = []
    with tempfile.TemporaryDirectory(prefix="newton_lab_refusals_") as folder:
        make_inputs(Path(folder))
        for argv, words in cases:
            results.append(time_case(command, argv, words, Path(folder)))
            if on_case is not None:
                on_case(results[-1])
    walls = [r["wall_s"] for r in results]
    return {
        "cases": len(results),
        "refused": sum(r["refused"] for r in results),
        "exit_2": sum(r["exit"] == 2 for r in results),
        "one_line": sum(r["one_line"] for r in results),
        "unchanged": sum(r["unchanged"] for r in results),
        "under_2_s": sum(w < 2.0 for w in walls),
        "wall_s": _spread(walls),
        "cpu_s": _spread([r["cpu_s"] for r in results]),
        "slowest": [
            {"argv": r["argv"], "wall_s": r["wall_s"]} for r in sorted(results, key=lambda r: -r["wall_s"])[:SLOWEST]
        ],
        "command": " ".join(Path(c).name for c in command),
        "per_case": results,
    }
