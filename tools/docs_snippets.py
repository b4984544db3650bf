"""The code blocks of the user guide, extracted, checked and run at their smallest size (``tests/test_docs.py``).

Every fenced ``python`` and ``bash`` block of ``docs/**/*.md`` is a *snippet*. Each one is checked: Python compiles,
and every ``newton-lab <command> --flag`` parses with the real command-line parser, each flag spelt exactly as the
parser spells it (so a flag that disappears fails the check). Then the snippets of each page run in page order,
like a notebook, from an empty working folder: Python blocks share one namespace per page, ``newton-lab ...`` lines
run in this process (``newton_lab.cli.main``) and ``python examples/...`` / ``python tools/...`` lines through
``runpy``, with sizes made small by ``shrink``. A snippet that cannot run in CI (a CUDA device, a GUI, a long job)
is marked on the line above its fence::

    <!-- check-only: needs a CUDA device -->

and is then only checked. A line with ``--device cuda`` is check-only by itself.

    python tools/docs_snippets.py check                       # every page: syntax and flags
    python tools/docs_snippets.py run docs/tutorial/simple_task.md [--workdir DIR] [--json OUT]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import runpy
import shlex
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(python|bash)([^\n]*)\n(.*?)^```", re.M | re.S)
INCLUDE = re.compile(r'^--8<-- "([^"]+)"$', re.M)
"""A ``pymdownx.snippets`` line: the block shows that repository file."""
CHECK_ONLY = re.compile(r"<!--\s*check-only:\s*(.+?)\s*-->\s*$")
SMALL = 2
"""Episodes and env rows a running snippet is cut to."""
TRAIN_STEPS = 2
"""Gradient steps of a running ``newton-lab train``."""
POLICY_STEPS = 40
"""Step limit of a running rollout of a trained checkpoint."""
SCRIPT_DIRS = ("examples/", "tools/")
"""``python <dir>/<script>`` lines run the repository's script (the working folder is empty)."""


@dataclass(frozen=True)
class Snippet:
    """One fenced block: where it is, its language and code, and why it only gets checked (``None``: it runs)."""

    page: str
    line: int
    lang: str
    code: str
    check_only: str | None
    listing: str | None = None
    """The repository file a ``title="path"`` block shows (whole or in part)."""

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"


def pages() -> list[Path]:
    """Every markdown page of the guide."""
    return sorted(DOCS.rglob("*.md"))


def snippets(path: Path) -> list[Snippet]:
    """The python and bash blocks of ``path`` in page order."""
    text = path.read_text()
    out = []
    for m in FENCE.finditer(text):
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        marker = CHECK_ONLY.search(before)
        code = INCLUDE.sub(lambda f: (ROOT / f.group(1)).read_text(), m.group(3))
        reason = marker.group(1) if marker else None
        title = re.search(r'title="([^"]+)"', m.group(2))
        if reason is None and title:
            reason = "a listing of the repository's file (the tasks package imports it)"
        if reason is None and m.group(1) == "bash" and "--device cuda" in code:
            reason = "needs a CUDA device"
        out.append(Snippet(str(path.relative_to(ROOT)), text[:m.start()].count("\n") + 1, m.group(1), code, reason,
                           title.group(1) if title else None))
    return out


def commands(code: str) -> list[str]:
    """The command lines of a bash block: continuation lines joined, comments and blank lines dropped."""
    joined = re.sub(r"\\\n\s*", " ", code)
    out = []
    for line in joined.splitlines():
        words = shlex.split(line, comments=True)
        if words:
            out.append(shlex.join(words))
    return out


# ------------------------------------------------------------------------------------------------ checks
@contextlib.contextmanager
def _no_exit():
    """argparse errors raise ``ValueError`` instead of exiting (stderr kept quiet)."""
    with open(os.devnull, "w") as null, contextlib.redirect_stderr(null), contextlib.redirect_stdout(null):
        try:
            yield
        except SystemExit as exc:
            raise ValueError("argparse refused the line") from exc


def check_cli(line: str) -> list[str]:
    """Problems of one ``newton-lab ...`` line: an unknown command, an unknown or misspelt flag."""
    from newton_lab.cli import build_parser

    words = shlex.split(line)[1:]
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices  # argparse keeps subparsers here only
    command = next((w for w in words if not w.startswith("-")), None)
    if command is None and words and set(words) <= {"--version", "--help", "-h", "--verbose"}:
        return []
    if command not in sub:
        return [f"unknown command {command!r} in: {line}"]
    flags = {s for a in sub[command]._actions for s in a.option_strings}
    problems = [f"no flag {w.split('=')[0]} in `newton-lab {command}`: {line}"
                for w in words if w.startswith("--") and w.split("=")[0] not in flags]
    if not problems:
        try:
            with _no_exit():
                _, extra = parser.parse_known_args(words)
            if extra:
                problems.append(f"unparsed {extra}: {line}")
        except ValueError as exc:
            problems.append(f"{exc}: {line}")
    return problems


def check_listing(snippet: Snippet) -> list[str]:
    """A listing's lines must be the file's, in the file's order (an excerpt may leave lines out)."""
    path = ROOT / snippet.listing
    if not path.is_file():
        return [f"{snippet.where}: no file {snippet.listing}"]
    lines = iter(line.rstrip() for line in path.read_text().splitlines())
    for shown in (line.rstrip() for line in snippet.code.splitlines() if line.strip()):
        if not any(line == shown for line in lines):
            return [f"{snippet.where}: {shown.strip()!r} is not in {snippet.listing} (or out of order)"]
    return []


def check(snippet: Snippet) -> list[str]:
    """Problems of one snippet (empty when it is fine)."""
    if snippet.listing:
        return check_listing(snippet)
    if snippet.lang == "python":
        try:
            compile(snippet.code, snippet.where, "exec")
        except SyntaxError as exc:
            return [f"{snippet.where}: {exc}"]
        return []
    problems = []
    for line in commands(snippet.code):
        words = shlex.split(line)
        if words[0] == "newton-lab":
            problems += [f"{snippet.where}: {p}" for p in check_cli(line)]
        elif words[0] == "python" and len(words) > 1 and words[1].startswith(SCRIPT_DIRS):
            if not (ROOT / words[1]).is_file():
                problems.append(f"{snippet.where}: no script {words[1]}")
    return problems


# ------------------------------------------------------------------------------------------------ shrink
def _cap(text: str, flag: str, value: int) -> str:
    return re.sub(rf"({re.escape(flag)}[ =])(\d+)", lambda m: f"{m.group(1)}{min(int(m.group(2)), value)}", text)


def shrink(line: str) -> str:
    """``line`` at its smallest size: episodes and rows cut to ``SMALL``, training to ``TRAIN_STEPS`` steps, rollouts
    of a checkpoint to ``POLICY_STEPS`` steps."""
    line = _cap(_cap(line, "--episodes", SMALL), "--num-envs", SMALL)
    words = shlex.split(line)
    if words[:2] == ["newton-lab", "train"]:
        line = _cap(line, "--max-steps", TRAIN_STEPS) if "--max-steps" in words else f"{line} --max-steps {TRAIN_STEPS}"
        line = re.sub(r"--time-budget-s[ =]\d+\s*", "", line)
    if words[0] == "newton-lab" and ("--checkpoint" in words or "--phase-checkpoint" in words):
        line = _cap(line, "--max-steps", POLICY_STEPS) if "--max-steps" in words else f"{line} --max-steps {POLICY_STEPS}"
    return line


def shrink_python(code: str) -> str:
    """A Python snippet at its smallest size (``num_envs=`` and ``episodes=`` cut to ``SMALL``)."""
    for name in ("num_envs", "episodes"):
        code = re.sub(rf"\b{name}=(\d+)", lambda m, n=name: f"{n}={min(int(m.group(1)), SMALL)}", code)
    return code


# ------------------------------------------------------------------------------------------------ run
def _run_line(line: str) -> None:
    words = shlex.split(shrink(line))
    if words[0] == "newton-lab":
        from newton_lab.cli import main

        try:
            status = main(words[1:])
        except SystemExit as exc:  # --version and --help exit
            status = exc.code or 0
        if status != 0:
            raise RuntimeError(f"exit status {status}")
    elif words[0] == "python" and len(words) > 1 and words[1].startswith(SCRIPT_DIRS):
        argv = sys.argv
        sys.argv = [str(ROOT / words[1]), *words[2:]]
        try:
            runpy.run_path(sys.argv[0], run_name="__main__")
        finally:
            sys.argv = argv
    else:
        raise ValueError(f"cannot run {words[0]!r} here: mark the block <!-- check-only: why -->")


def run_page(path: Path, workdir: Path) -> dict:
    """Run the running snippets of ``path`` in ``workdir``; a summary with the first failure, if any."""
    workdir.mkdir(parents=True, exist_ok=True)
    namespace: dict = {"__name__": "__docs__"}
    ran, start, here = 0, time.perf_counter(), Path.cwd()
    os.chdir(workdir)
    try:
        for snippet in snippets(path):
            if snippet.check_only:
                continue
            try:
                if snippet.lang == "python":
                    exec(compile(shrink_python(snippet.code), snippet.where, "exec"), namespace)
                else:
                    for line in commands(snippet.code):
                        _run_line(line)
            except BaseException as exc:  # noqa: BLE001  (SystemExit of a script included)
                return {"page": str(path.relative_to(ROOT)), "ran": ran, "failed": snippet.where,
                        "error": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc()[-3000:]}
            ran += 1
    finally:
        os.chdir(here)
    return {"page": str(path.relative_to(ROOT)), "ran": ran, "failed": None, "seconds": time.perf_counter() - start}


def _resolve(names: list[str]) -> list[Path]:
    return [(ROOT / n).resolve() if not Path(n).is_absolute() else Path(n) for n in names] if names else pages()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="check or run the user guide's code blocks")
    parser.add_argument("mode", choices=("check", "run"))
    parser.add_argument("pages", nargs="*", help="markdown pages (default: every page of docs/)")
    parser.add_argument("--workdir", help="working folder of the runs, one subfolder a page (default: a new temporary one)")
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args(argv)
    paths = _resolve(args.pages)
    if args.mode == "check":
        problems = [p for path in paths for s in snippets(path) for p in check(s)]
        print("\n".join(problems) or f"{sum(len(snippets(p)) for p in paths)} snippets checked")
        return 1 if problems else 0
    workdir = Path(args.workdir or tempfile.mkdtemp(prefix="docs_run_")).resolve()
    results = [run_page(p, workdir / "_".join(p.relative_to(DOCS).with_suffix("").parts)) for p in paths]
    if args.json:
        Path(args.json).write_text(json.dumps(results))
    for r in results:
        print(json.dumps({k: v for k, v in r.items() if k != "trace"}))
    return 1 if any(r["failed"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
