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

A page the reader builds on (the tutorial's chapters: two of them write a task package) says so in one line,
``<!-- run-in: a scratch copy of the repository -->``: it runs in a copy of the working tree (``tools/mutations.py``'s
``scratch_copy``, every ``newton_lab`` package importing from the copy), from the copy's root, at the sizes the
page writes (only training and rollouts of a checkpoint are cut). Commands run in this process until the page
writes a file after the task packages were read here; from then on each runs in a process of its own, as a
reader's does, and sees the package just written (Python blocks share one namespace, as in a notebook). On such
a page:

- a block marked ``<!-- write-file -->`` whose fence has ``title="PATH"`` is a file the reader writes: the run
  writes it to ``PATH`` (the check compiles Python and parses YAML);
- ``mkdir -p DIR`` and ``cp FILE NEW_FILE`` lines run (a copy is a file the page writes);
- a block marked ``<!-- fails: why -->`` shows a command that is refused: it runs, and passes only when refused;
- a ``text`` block marked ``<!-- output -->`` is what the runnable block before it prints (stdout and stderr, as
  a terminal shows them), and the run compares
  them: whitespace and line breaks are free, ``...`` stands for anything, every other character must match, and
  every number must equal the one printed, or lie within the tolerance the marker states:
  ``<!-- output: numbers within 5 % -->``, ``<!-- output: numbers within 0.002 -->``, or
  ``<!-- output: structure, because ... -->`` (numbers not compared, each still a number where it stands).

    python tools/docs_snippets.py check                       # every page: syntax and flags
    python tools/docs_snippets.py run docs/tutorial/simple_task.md [--workdir DIR] [--json OUT]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import re
import runpy
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r"^```(python|bash|yaml|text)([^\n]*)\n(.*?)^```", re.M | re.S)
"""A fenced block; ``yaml`` ones count as snippets only when the reader writes them, ``text`` ones only as
outputs."""
INCLUDE = re.compile(r'^--8<-- "([^"]+)"$', re.M)
"""A ``pymdownx.snippets`` line: the block shows that repository file."""
CHECK_ONLY = re.compile(r"<!--\s*check-only:\s*(.+?)\s*-->\s*$")
WRITE_FILE = re.compile(r"<!--\s*write-file\s*-->\s*$")
FAILS = re.compile(r"<!--\s*fails:\s*(.+?)\s*-->\s*$")
"""A block whose command must be refused (a page showing an error): it runs, and passes only when it fails."""
OUTPUT = re.compile(r"<!--\s*output(?::\s*(.+?))?\s*-->\s*$")
IN_COPY = re.compile(r"^<!--\s*run-in:\s*a scratch copy of the repository\s*-->\s*$", re.M)
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
    writes: str | None = None
    """The file a ``<!-- write-file -->`` block has the reader write (a path from the working folder)."""
    fails: str | None = None
    """Why the block's command must be refused (``<!-- fails: why -->``): the run passes only when it is."""

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"


@dataclass(frozen=True)
class Output:
    """A ``<!-- output -->`` text block: what the runnable snippet before it prints, and how numbers compare."""

    page: str
    line: int
    text: str
    tolerance: str
    """``exact``, ``structure``, ``N %`` (relative) or ``N`` (absolute), from the marker."""
    after: int | None
    """Line of the runnable snippet whose output this is (``None``: no runnable snippet before it)."""

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"


def pages() -> list[Path]:
    """Every markdown page of the guide."""
    return sorted(DOCS.rglob("*.md"))


def in_copy(path: Path) -> bool:
    """Whether the page runs in a scratch copy of the repository (``<!-- run-in: ... -->``)."""
    return bool(IN_COPY.search(path.read_text()))


def _line_before(text: str, start: int) -> str:
    return text[:start].rstrip("\n").rsplit("\n", 1)[-1]


def snippets(path: Path) -> list[Snippet]:
    """The python and bash blocks of ``path`` in page order, and the files it has the reader write."""
    text = path.read_text()
    out = []
    for m in FENCE.finditer(text):
        before = _line_before(text, m.start())
        lang = m.group(1)
        title = re.search(r'title="([^"]+)"', m.group(2))
        writes = title.group(1) if title and WRITE_FILE.search(before) else None
        if lang == "text" or (lang == "yaml" and writes is None):
            continue
        marker = CHECK_ONLY.search(before)
        code = INCLUDE.sub(lambda f: (ROOT / f.group(1)).read_text(), m.group(3))
        reason = marker.group(1) if marker else None
        if reason is None and title and writes is None:
            reason = "a listing of the repository's file (the tasks package imports it)"
        if reason is None and lang == "bash" and "--device cuda" in code:
            reason = "needs a CUDA device"
        fails = FAILS.search(before)
        out.append(
            Snippet(
                str(path.relative_to(ROOT)),
                text[: m.start()].count("\n") + 1,
                lang,
                code,
                reason,
                title.group(1) if title and writes is None else None,
                writes,
                fails.group(1) if fails else None,
            )
        )
    return out


def outputs(path: Path) -> list[Output]:
    """The ``<!-- output -->`` blocks of ``path``, each tied to the runnable snippet before it."""
    text = path.read_text()
    runnable = [s.line for s in snippets(path) if s.check_only is None and s.writes is None]
    out = []
    for m in FENCE.finditer(text):
        marker = OUTPUT.search(_line_before(text, m.start()))
        if m.group(1) != "text" or not marker:
            continue
        line = text[: m.start()].count("\n") + 1
        tolerance = (marker.group(1) or "exact").strip()
        if tolerance.startswith("structure"):
            tolerance = "structure"
        else:
            found = re.fullmatch(r"(?:numbers within\s+)?([0-9.]+)\s*(%?)|exact", tolerance)
            if not found:
                raise ValueError(
                    f"{path}:{line}: output tolerance {tolerance!r}: say exact, structure, "
                    "numbers within N %, or numbers within N"
                )
            tolerance = "exact" if tolerance == "exact" else f"{found.group(1)}{' %' if found.group(2) else ''}"
        before = [n for n in runnable if n < line]
        out.append(Output(str(path.relative_to(ROOT)), line, m.group(3), tolerance, before[-1] if before else None))
    return out


# ------------------------------------------------------------------------------------------------ outputs
NUMBER = r"(?<![\w.])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w])"
"""A number as a page shows it: not part of a name (``v0``, ``joint1``)."""
_TOKEN = re.compile(rf"(?P<ellipsis>\.\.\.|…)|(?P<number>{NUMBER})|(?P<space>\s+)|(?P<other>.)", re.S)


def _close(shown: str, got: str, tolerance: str) -> bool:
    if tolerance == "structure":
        return True
    a, b = float(shown), float(got)
    if tolerance == "exact":
        return a == b
    if tolerance.endswith("%"):
        return abs(a - b) <= float(tolerance[:-1].strip()) / 100 * abs(a)
    return abs(a - b) <= float(tolerance)


def compare_output(shown: str, printed: str, tolerance: str = "exact") -> str | None:
    """``None`` when ``printed`` holds ``shown`` (whitespace free, ``...`` anything, numbers within
    ``tolerance``), else what differs."""
    parts, numbers = [], []
    for t in _TOKEN.finditer(shown.strip()):
        if t.lastgroup == "ellipsis":
            parts.append(".*?")
        elif t.lastgroup == "number":
            parts.append(f"({NUMBER})")
            numbers.append(t.group())
        elif t.lastgroup == "space":
            parts.append(r"\s*")
        else:
            parts.append(r"\s*" + re.escape(t.group()) if t.group() in ",:;)]}" else re.escape(t.group()))
    pattern = re.compile("".join(parts), re.S)
    match, off, pos = pattern.search(printed), [], 0
    if match is None:
        return f"the printed output has no text of this shape; it printed:\n{printed[-3000:]}"
    while match is not None:  # every place the shape starts, until one holds the numbers
        off = [(s, g) for s, g in zip(numbers, match.groups()) if not _close(s, g, tolerance)]
        if not off:
            return None
        pos = match.start() + 1
        match = pattern.search(printed, pos)
    return (
        f"numbers outside the tolerance ({tolerance}): "
        + ", ".join(f"shown {s}, printed {g}" for s, g in off)
        + f"\nprinted:\n{printed[-3000:]}"
    )


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
    problems = [
        f"no flag {w.split('=')[0]} in `newton-lab {command}`: {line}"
        for w in words
        if w.startswith("--") and w.split("=")[0] not in flags
    ]
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
    """A listing's lines must be the file's text, in the file's order: an excerpt may leave lines out, and a long
    line may be shown wrapped (whitespace and line breaks are free), but nothing else may differ."""
    path = ROOT / snippet.listing
    if not path.is_file():
        return [f"{snippet.where}: no file {snippet.listing}"]
    text, at = " ".join(path.read_text().split()), 0
    for shown in (" ".join(line.split()) for line in snippet.code.splitlines() if line.strip()):
        found = text.find(shown, at)
        if found < 0:
            return [f"{snippet.where}: {shown!r} is not in {snippet.listing} (or out of order)"]
        at = found + len(shown)
    return []


def check(snippet: Snippet) -> list[str]:
    """Problems of one snippet (empty when it is fine)."""
    if snippet.listing:
        return check_listing(snippet)
    if snippet.writes and snippet.lang == "yaml":
        import yaml

        try:
            yaml.safe_load(snippet.code)
        except yaml.YAMLError as exc:
            return [f"{snippet.where}: {snippet.writes} is no YAML: {exc}"]
        return []
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


def check_outputs(path: Path) -> list[str]:
    """Problems of a page's ``<!-- output -->`` blocks: a tolerance that does not parse, no command before one."""
    try:
        found = outputs(path)
    except ValueError as exc:
        return [str(exc)]
    return [f"{o.where}: an output block with no runnable block before it" for o in found if o.after is None]


# ------------------------------------------------------------------------------------------------ shrink
def _cap(text: str, flag: str, value: int) -> str:
    return re.sub(rf"({re.escape(flag)}[ =])(\d+)", lambda m: f"{m.group(1)}{min(int(m.group(2)), value)}", text)


def shrink(line: str, sizes: bool = True) -> str:
    """``line`` at its smallest size: episodes and rows cut to ``SMALL`` (unless not ``sizes``: a page run at the
    sizes it writes), training to ``TRAIN_STEPS`` steps, rollouts of a checkpoint to ``POLICY_STEPS`` steps."""
    if sizes:
        line = _cap(_cap(line, "--episodes", SMALL), "--num-envs", SMALL)
    words = shlex.split(line)
    if words[:2] == ["newton-lab", "train"]:
        line = _cap(line, "--max-steps", TRAIN_STEPS) if "--max-steps" in words else f"{line} --max-steps {TRAIN_STEPS}"
        line = re.sub(r"--time-budget-s[ =]\d+\s*", "", line)
    if words[0] == "newton-lab" and ("--checkpoint" in words or "--phase-checkpoint" in words):
        line = (
            _cap(line, "--max-steps", POLICY_STEPS) if "--max-steps" in words else f"{line} --max-steps {POLICY_STEPS}"
        )
    return line


def shrink_python(code: str) -> str:
    """A Python snippet at its smallest size (``num_envs=`` and ``episodes=`` cut to ``SMALL``)."""
    for name in ("num_envs", "episodes"):
        code = re.sub(rf"\b{name}=(\d+)", lambda m, n=name: f"{n}={min(int(m.group(1)), SMALL)}", code)
    return code


# ------------------------------------------------------------------------------------------------ run
class _Tee(io.TextIOBase):
    """Writes go to ``stream`` and are kept in ``kept`` (the output a page's block is compared with)."""

    def __init__(self, stream, kept: io.StringIO | None = None):
        self.stream, self.kept = stream, kept if kept is not None else io.StringIO()

    def write(self, text):
        self.kept.write(text)
        return self.stream.write(text)

    def flush(self):
        self.stream.flush()

    def isatty(self):
        return False


def _run_line(line: str, sizes: bool = True, process: bool = False) -> list[str]:
    """Run one command line (in a process of its own if ``process``); the files it made that a page writes
    (``cp``)."""
    words = shlex.split(shrink(line, sizes))
    if process and words[0] in ("newton-lab", "python"):
        _run_process(words)
    elif words[0] == "newton-lab":
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
    elif words[:2] == ["mkdir", "-p"] and len(words) > 2 and not sizes:
        for folder in words[2:]:
            Path(folder).mkdir(parents=True, exist_ok=True)
    elif words[0] == "cp" and len(words) == 3 and not sizes:
        _inside(words[2])
        shutil.copyfile(words[1], words[2])
        return [words[2]]
    else:
        raise ValueError(f"cannot run {words[0]!r} here: mark the block <!-- check-only: why -->")
    return []


def _imported() -> bool:
    """Whether this process has read the task packages (it would not see one written now)."""
    return any(name in sys.modules for name in ("newton_lab.tasks", "newton_lab.task_api.catalog"))


def _run_process(words: list[str]) -> None:
    """A reader's command in a process of its own (it sees the task packages the page wrote before it), its output
    passed on to this process's (possibly captured) streams."""
    script = Path(sys.executable).parent / "newton-lab"
    if words[0] == "newton-lab":
        argv = (
            [str(script), *words[1:]]
            if script.is_file()
            else [sys.executable, "-c", "import sys; from newton_lab.cli import main; sys.exit(main())", *words[1:]]
        )
    else:
        argv = [sys.executable, *words[1:]]
    proc = subprocess.run(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        check=False,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # both streams in the order printed
    sys.stdout.write(proc.stdout)
    if proc.returncode != 0:
        raise RuntimeError(f"exit status {proc.returncode}")


def _inside(name: str) -> Path:
    path = Path(name)
    if path.is_absolute() or ".." in path.parts:
        raise ValueError(f"a written file must be a path inside the working folder: {path}")
    if path.exists():
        raise FileExistsError(f"{path} exists already; the page writes it from nothing")
    return path


def _write(snippet: Snippet) -> None:
    path = _inside(snippet.writes)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(snippet.code)


def run_page(path: Path, workdir: Path) -> dict:
    """Run the runnable snippets of ``path`` in ``workdir`` (a page marked ``run-in: a scratch copy`` in a copy of
    the repository made there); a summary with the first failure, if any."""
    if in_copy(path):
        return run_in_copy(path, workdir / "repo")
    return _run(path, workdir, sizes=True)


def _run(path: Path, workdir: Path, sizes: bool) -> dict:
    workdir.mkdir(parents=True, exist_ok=True)
    namespace: dict = {"__name__": "__docs__"}
    ran, wrote, start, here = 0, [], time.perf_counter(), Path.cwd()
    process = False  # set once the page writes a file after this process imported the task packages
    printed: dict[int, str] = {}
    page = str(path.relative_to(ROOT))
    os.chdir(workdir)
    try:
        for snippet in snippets(path):
            if snippet.check_only:
                continue
            tee = _Tee(sys.stdout)
            try:
                if snippet.writes:
                    process = process or _imported()
                    _write(snippet)
                    wrote.append(snippet.writes)
                    continue
                with contextlib.redirect_stdout(tee), contextlib.redirect_stderr(_Tee(sys.stderr, tee.kept)):
                    try:
                        if snippet.lang == "python":
                            code = shrink_python(snippet.code) if sizes else snippet.code
                            exec(compile(code, snippet.where, "exec"), namespace)
                        else:
                            for line in commands(snippet.code):
                                if line.startswith("cp "):
                                    process = process or _imported()
                                wrote += _run_line(line, sizes, process)
                    except Exception:
                        if not snippet.fails:
                            raise
                    else:
                        if snippet.fails:
                            raise RuntimeError(f"the page says this is refused ({snippet.fails}), but it ran")
            except BaseException as exc:  # noqa: BLE001  (SystemExit of a script included)
                return {
                    "page": page,
                    "ran": ran,
                    "failed": snippet.where,
                    "error": f"{type(exc).__name__}: {exc}",
                    "trace": traceback.format_exc()[-3000:],
                    "wrote": wrote,
                }
            printed[snippet.line] = tee.kept.getvalue()
            ran += 1
    finally:
        os.chdir(here)
    compared, differ = 0, []
    for out in outputs(path):
        if out.after not in printed:
            continue
        compared += 1
        problem = compare_output(out.text, printed[out.after], out.tolerance)
        if problem:
            differ.append(f"{out.where} (output of line {out.after}): {problem}")
    result = {
        "page": page,
        "ran": ran,
        "failed": None,
        "seconds": time.perf_counter() - start,
        "wrote": wrote,
        "outputs_compared": compared,
    }
    if differ:
        result.update(
            failed=differ[0].split(" ", 1)[0],
            error="shown output differs from the printed one",
            trace="\n\n".join(differ)[-6000:],
        )
    return result


def _tree(root: Path) -> set[str]:
    return {
        str(p.relative_to(root))
        for p in root.rglob("*")
        if p.is_file() and "__pycache__" not in p.parts and p.parts[len(root.parts)] != "outputs"
    }


def run_in_copy(path: Path, copy: Path) -> dict:
    """Run ``path`` in a fresh scratch copy of the working tree at ``copy``, from its root, at the page's sizes, in
    a process of its own (the copy's packages import from the copy). The summary adds ``stray``: files the run
    left outside ``outputs/`` that the page does not write."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import mutations  # tools/mutations.py: the same copy its mutants run in

    page = str(path.relative_to(ROOT))
    copy.mkdir(parents=True, exist_ok=False)
    mutations.scratch_copy(copy)
    writes = [s.writes for s in snippets(path) if s.writes]
    there = [w for w in writes if (copy / w).exists()]
    if there:
        return {
            "page": page,
            "ran": 0,
            "failed": page,
            "error": f"{', '.join(there)} exist in the working tree; the "
            "page writes them from nothing (remove them there)",
            "trace": "",
        }
    before = _tree(copy)
    out = copy / "outputs" / "docs_run.json"
    env = {**mutations.environment(copy), "PYTHONPATH": str(copy)}
    proc = subprocess.run(
        [sys.executable, str(copy / "tools" / "docs_snippets.py"), "run", page, "--here", "--json", str(out)],
        cwd=copy,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    if not out.is_file():
        return {
            "page": page,
            "ran": 0,
            "failed": page,
            "error": f"exit status {proc.returncode}",
            "trace": (proc.stdout + proc.stderr)[-5000:],
        }
    result = json.loads(out.read_text())[0]
    result["stray"] = sorted(_tree(copy) - before - set(writes) - set(result.get("wrote", ())))
    result["log"] = (proc.stdout + proc.stderr)[-20000:]
    return result


def _here(path: Path) -> dict:
    """Run ``path`` from this repository's root, which must be a scratch copy: refuses the working tree whose
    packages the editable install maps (a page that writes a task would leave it there)."""
    import importlib.util

    for name in ("newton_lab", "newton_lab.tasks", "newton_lab.kernels"):  # located, not imported: the task
        # packages are found when newton_lab.tasks is first imported, after the page wrote its own
        where = [Path(p).resolve() for p in importlib.util.find_spec(name).submodule_search_locations]
        if not all(ROOT in p.parents for p in where):
            sys.exit(
                f"{name} resolves to {where}, outside {ROOT}: --here runs only in a scratch copy (PYTHONPATH=<copy>)"
            )
    return _run(path, ROOT, sizes=False)


def _resolve(names: list[str]) -> list[Path]:
    return [(ROOT / n).resolve() if not Path(n).is_absolute() else Path(n) for n in names] if names else pages()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="check or run the user guide's code blocks")
    parser.add_argument("mode", choices=("check", "run"))
    parser.add_argument("pages", nargs="*", help="markdown pages (default: every page of docs/)")
    parser.add_argument(
        "--workdir", help="working folder of the runs, one subfolder a page (default: a new temporary one)"
    )
    parser.add_argument("--json", help="write the results here")
    parser.add_argument(
        "--here",
        action="store_true",
        help="run from this repository's root at the page's sizes (only inside a scratch copy)",
    )
    args = parser.parse_args(argv)
    paths = _resolve(args.pages)
    if args.mode == "check":
        problems = [p for path in paths for s in snippets(path) for p in check(s)]
        problems += [p for path in paths for p in check_outputs(path)]
        print("\n".join(problems) or f"{sum(len(snippets(p)) for p in paths)} snippets checked")
        return 1 if problems else 0
    if args.here:
        results = [_here(p) for p in paths]
    else:
        workdir = Path(args.workdir or tempfile.mkdtemp(prefix="docs_run_")).resolve()
        results = [run_page(p, workdir / "_".join(p.relative_to(DOCS).with_suffix("").parts)) for p in paths]
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(results))
    for r in results:
        print(json.dumps({k: v for k, v in r.items() if k not in ("trace", "log")}))
    return 1 if any(r["failed"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
