"""Curated mutation run: break one promise of the README at a time in a scratch copy and check its tests notice.

Each :class:`Mutation` is a small exact text patch (one or more hunks) of the code that keeps one promise, and the
pytest arguments (files or node ids) of the tests that claim to cover it. The working tree's files (tracked and
not ignored) are copied once to a scratch folder; each patch is applied there in turn and undone after its run
(never in the working tree: Warp reads ``kernels/`` and ``tasks/`` at kernel build and other runs use them), and
the covering tests run with ``-x`` from the copy, ``PYTHONPATH`` pointing at it. A test failure kills the
mutation; all tests passing lets it survive.

    python tools/mutations.py              run every mutation; exit 1 on a survivor, 2 on an error
    python tools/mutations.py --check      only check that every patch still applies (no pytest)
    python tools/mutations.py --only NAME  the named mutations (repeatable); --list prints them
    python tools/mutations.py --baseline   also run each covering set unmutated first (it must pass)

The copy keeps the installed layout: ``newton_lab/{kernels,tasks,flows,assets}`` are links to the copy's top-level
folders (setup.py maps them there), and a pre-flight import checks that every ``newton_lab`` package resolves
inside the copy, not to the editable install of the working tree.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # tools/ is no package: the list sits beside this file
from mutation_cases import MUTATIONS, Mutation  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
MAPPED = ("kernels", "tasks", "flows", "assets")
"""Top-level folders setup.py installs as ``newton_lab.<name>``."""
TIMEOUT_S = 900
"""Longest a mutation's covering tests may run [s] (a hang is reported, not counted as a kill)."""


class PatchError(ValueError):
    """A mutation's patch no longer applies to the source (its text is gone or not unique)."""


def patched(text: str, mutation: Mutation, path: str) -> str:
    """``text`` of ``path`` with the mutation's hunks for that file applied; :class:`PatchError` naming the
    mutation if a hunk's old text is not found exactly once."""
    for hunk_path, old, new in mutation.hunks:
        if hunk_path != path:
            continue
        count = text.count(old)
        if count != 1:
            raise PatchError(
                f"mutation {mutation.name}: its patch of {path} no longer applies (the text to replace "
                f"occurs {count} times, expected once): update it in tools/mutation_cases.py"
            )
        text = text.replace(old, new)
    return text


def check(root: Path = REPO, mutations: tuple[Mutation, ...] = MUTATIONS) -> list[str]:
    """One line per mutation whose patch does not apply to ``root`` or whose covering tests are missing."""
    problems = []
    for m in mutations:
        try:
            for path in dict.fromkeys(p for p, _, _ in m.hunks):
                patched((root / path).read_text(), m, path)
        except (PatchError, FileNotFoundError) as e:
            problems.append(str(e))
        problems += [
            f"mutation {m.name}: covering test {t} does not exist"
            for t in m.tests
            if not (root / t.split("::")[0]).is_file()
        ]
    return problems


def scratch_copy(dest: Path) -> None:
    """The working tree's files (tracked, and untracked ones git does not ignore: what the tests here import) into
    ``dest``, with the installed package layout."""
    names = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        check=True,
        capture_output=True,
    ).stdout
    for rel in dict.fromkeys(filter(None, names.decode().split("\0"))):
        src = REPO / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel, follow_symlinks=False)
    for name in MAPPED:
        (dest / "newton_lab" / name).symlink_to(Path("..") / name)


PREFLIGHT = """
import importlib, sys
from pathlib import Path
root = Path(sys.argv[1]).resolve()
for name in ("newton_lab", "newton_lab.kernels", "newton_lab.tasks", "newton_lab.flows", "newton_lab.assets"):
    where = [Path(p).resolve() for p in importlib.import_module(name).__path__]
    if not all(root in p.parents for p in where):
        sys.exit(f"{name} resolves to {where}, not inside the scratch copy {root}")
"""


def environment(copy: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    return {**env, "PYTHONPATH": str(copy)}


def run_tests(copy: Path, tests: tuple[str, ...]) -> tuple[str, float, str]:
    """(outcome, seconds, what to show): ``passed`` (exit 0), ``failed`` (exit 1: the first failed test), else
    ``error`` or ``timeout`` (the output's last lines)."""
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, cwd=copy, env=environment(copy), capture_output=True, text=True, timeout=TIMEOUT_S, check=False
        )
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - t0, f"no result after {TIMEOUT_S} s"
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    outcome = {0: "passed", 1: "failed"}.get(proc.returncode, "error")
    failed = [line.split()[1] for line in lines if line.startswith("FAILED ")]
    return outcome, time.perf_counter() - t0, failed[0] if outcome == "failed" and failed else "\n".join(lines[-6:])


def apply(copy: Path, mutation: Mutation, revert: dict[str, str] | None = None) -> dict[str, str]:
    """Patch the copy (or, with ``revert``, put the saved texts back); returns the original texts by path."""
    saved = {}
    for path in dict.fromkeys(p for p, _, _ in mutation.hunks):
        target = copy / path
        text = target.read_text()
        saved[path] = text
        target.write_text(revert[path] if revert else patched(text, mutation, path))
        for stale in target.parent.glob(f"__pycache__/{target.stem}.*.pyc"):
            stale.unlink()  # a same-size rewrite within the second would reuse the other text's bytecode
    return saved


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check that every patch applies")
    parser.add_argument("--list", action="store_true", help="print the mutations and their covering tests")
    parser.add_argument("--only", action="append", default=[], metavar="NAME", help="run only this mutation")
    parser.add_argument("--baseline", action="store_true", help="run each covering set unmutated first")
    args = parser.parse_args(argv)
    chosen = tuple(m for m in MUTATIONS if not args.only or m.name in args.only)
    unknown = set(args.only) - {m.name for m in MUTATIONS}
    if unknown:
        print(f"unknown mutation(s): {', '.join(sorted(unknown))}; --list names them", file=sys.stderr)
        return 2
    if args.list:
        for m in chosen:
            print(f"{m.name:32s} {m.promise}\n{'':32s} {' '.join(m.tests)}")
        return 0
    problems = check(REPO, chosen)
    for line in problems:
        print(line, file=sys.stderr)
    if problems or args.check:
        print(f"{len(chosen) - len(problems)} of {len(chosen)} mutations apply", file=sys.stderr)
        return 2 if problems else 0
    return run(chosen, args.baseline)


def run(chosen: tuple[Mutation, ...], baseline: bool) -> int:
    """Run every mutation in one scratch copy (restored after each); prints the table, returns the exit code."""
    t_start, rows = time.perf_counter(), []
    with tempfile.TemporaryDirectory(prefix="newton_lab_mutants_") as tmp:
        copy = Path(tmp) / "repo"
        scratch_copy(copy)
        pre = subprocess.run(
            [sys.executable, "-c", PREFLIGHT, str(copy)],
            cwd=copy,
            env=environment(copy),
            capture_output=True,
            text=True,
            check=False,
        )
        if pre.returncode != 0:
            print(f"pre-flight: {pre.stderr.strip()}", file=sys.stderr)
            return 2
        if baseline:
            for tests in dict.fromkeys(m.tests for m in chosen):
                outcome, seconds, tail = run_tests(copy, tests)
                print(f"baseline {' '.join(tests)}: {outcome} ({seconds:.0f} s)", flush=True)
                if outcome != "passed":
                    print(tail, file=sys.stderr)
                    return 2
        print(f"{'mutation':32s} {'result':9s} {'s':>5s}  covering tests -> the first that failed", flush=True)
        for m in chosen:
            saved = apply(copy, m)
            try:
                outcome, seconds, tail = run_tests(copy, m.tests)
            finally:
                apply(copy, m, revert=saved)
            result = {"failed": "killed", "passed": "SURVIVED"}.get(outcome, outcome.upper())
            rows.append(result)
            killer = f" -> {tail}" if result == "killed" else ""
            print(f"{m.name:32s} {result:9s} {seconds:5.0f}  {' '.join(m.tests)}{killer}", flush=True)
            if result not in ("killed", "SURVIVED"):
                print("    " + tail.replace("\n", "\n    "), flush=True)
    killed = rows.count("killed")
    print(f"{killed} of {len(rows)} killed in {time.perf_counter() - t_start:.0f} s", flush=True)
    if any(r not in ("killed", "SURVIVED") for r in rows):
        return 2
    return 0 if killed == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
