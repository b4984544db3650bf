"""The README is a front page: at most ``MAX_LINES`` lines, every link into the repository resolves, and no benchmark
history (figures live in docs/benchmarks.md). Its first sections run as written: every ```python and ```bash block
above "## Tasks" (the header, the Tour, the command line, gymnasium) is executed from an empty folder, the way a
newcomer copies it, in a subprocess of this venv's ``python`` (the bash lines with this venv's ``bin`` first on
``PATH``, so ``newton-lab`` and ``python`` are this install's).

Only sizes are changed, each by an explicit substitution in ``SMALLER`` that must match exactly as often as it says
(when the README changes, this test fails and names the substitution instead of silently running full size). Paths
stay as written: the Tour's ``data/pick_cube.hdf5`` goes into a folder that does not exist yet, as it would for a
newcomer (issue 36). Lines skipped, and why, are in ``SKIPPED``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from newton_lab.datasets import read_dataset_info

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
BIN = Path(sys.executable).parent
MAX_LINES = 200
FIRST_SECTIONS_END = "\n## Tasks\n"
"""The blocks checked are those above this heading (the later ones are excerpts of task configs)."""

SMALLER: dict[str, list[tuple[str, str, int]]] = {
    # block id -> [(regex, replacement, expected number of matches)]
    "tour": [(r"\bepisodes=20\b", "episodes=2", 2)],  # collect and evaluate: 2 episodes each, same path
    "newton-lab collect": [(r"--episodes 10\b", "--episodes 1", 1)],  # PushCube: one episode is enough
    # (newton-lab evaluate on Reach runs as written: 20 episodes of ~18 steps cost no more than 2)
    # the example scripts live in the clone, not in the newcomer's empty folder
    "python examples/01_collect.py": [
        (r"--episodes 4\b", "--episodes 1", 1),
        (r"(?<![\w/])examples/", f"{ROOT}/examples/", 1),
    ],
}
SKIPPED = {
    "make demo": "the demo pipeline itself (its time: its run records; tests/test_flows.py runs the pipeline small)",
    "make test": "the test suite itself",
}
NEEDS_CUDA = "--device cuda"
"""A line with this needs a CUDA device (``bench ... --device cuda:0``): skipped on a machine without one."""


def _blocks() -> list[tuple[str, str]]:
    """(language, code) of each fenced python / bash block of the README's first sections."""
    head = README.read_text().split(FIRST_SECTIONS_END, 1)[0]
    return re.findall(r"^```(python|bash)\n(.*?)^```", head, flags=re.M | re.S)


def _block_id(lang: str, code: str) -> str:
    if "make_env(" in code:
        return "tour"
    if "gymnasium" in code:
        return "gymnasium"
    return f"{lang}: {code.splitlines()[0].split('#')[0].strip()}"


BLOCKS = {_block_id(lang, code): (lang, code) for lang, code in _blocks()}


def _smaller(key: str, code: str) -> str:
    for pattern, repl, expected in SMALLER.get(key, ()):
        code, n = re.subn(pattern, repl, code)
        assert n == expected, (
            f"README changed: {pattern!r} matched {n} times in {key!r}, expected {expected}; "
            "update SMALLER in tests/test_readme.py"
        )
    return code


def _cuda() -> bool:
    import warp as wp

    return wp.is_cuda_available()


def _env() -> dict[str, str]:
    return {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}


def _run(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    out = subprocess.run(argv, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"{argv} exited {out.returncode}:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    return out


@pytest.fixture
def empty(tmp_path) -> Path:
    """An empty working folder (scripts are written beside it, not into it)."""
    work = tmp_path / "work"
    work.mkdir()
    return work


def test_the_first_sections_hold_the_blocks_this_test_runs():
    """Every block of the first sections is one this test runs (a new one needs a decision here)."""
    assert list(BLOCKS) == ["bash: make demo", "tour", "bash: newton-lab tasks", "gymnasium"], list(BLOCKS)
    assert 'path="data/pick_cube.hdf5"' in BLOCKS["tour"][1]  # the missing-folder case stays exercised
    header = [line for line in BLOCKS["bash: make demo"][1].splitlines() if line.strip()]
    assert [line.split("#")[0].strip() for line in header] == list(SKIPPED)


def test_the_readme_is_a_front_page():
    """Short, its links resolve, and its figures are the demo's only (the rest is in docs/benchmarks.md)."""
    text = README.read_text()
    assert len(text.splitlines()) <= MAX_LINES
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert "docs/tutorial/simple_task.md" in links and "docs/benchmarks.md" in links
    missing = [link for link in links if "://" not in link and not (ROOT / link).exists()]
    assert not missing, missing
    assert not re.search(r"demos/s|env-steps/s|samples/s|demos per hour", text), "benchmark figures belong in docs/"


def test_tour_runs_as_written_from_an_empty_folder(empty):
    script = empty.parent / "tour.py"
    script.write_text(_smaller("tour", BLOCKS["tour"][1]))
    out = _run([sys.executable, str(script)], empty)
    collected, evaluated = out.stdout.strip().splitlines()[-2:]
    assert 0 <= float(collected.split()[0]) <= 1 and 0 <= float(evaluated) <= 1, out.stdout  # the two prints
    assert read_dataset_info(empty / "data" / "pick_cube.hdf5")["num_demos"] == 2


def test_gymnasium_block_runs_as_written(empty):
    script = empty.parent / "gym_block.py"
    script.write_text(BLOCKS["gymnasium"][1])
    _run([sys.executable, str(script)], empty)


def test_command_line_block_runs_from_an_empty_folder(empty):
    assert shutil.which("newton-lab", path=str(BIN)) is not None, f"no newton-lab in {BIN}: pip install -e ."
    lines = [line for line in BLOCKS["bash: newton-lab tasks"][1].splitlines() if line.strip()]
    ran = []
    for line in lines:
        command = " ".join(line.split()[:2])
        if NEEDS_CUDA in line and not _cuda():
            continue
        out = _run(["bash", "-c", _smaller(command, line)], empty)
        ran.append(command)
        if command == "newton-lab tasks":
            assert "GalbotG1-PickCube-v0" in out.stdout
    assert {"newton-lab tasks", "newton-lab collect", "newton-lab evaluate", "python examples/01_collect.py"} <= {*ran}
    assert read_dataset_info(empty / "data" / "push.hdf5")["num_demos"] == 1
    assert read_dataset_info(empty / "data" / "pick_cube_demos.hdf5")["num_demos"] == 1  # the example's default
