"""``newton-lab pipeline`` stopped midway, on the embedded Prefect server (uvicorn, started by Prefect's ephemeral
mode): Ctrl-C ends it in one line (the stages that finished, where) with exit status 130, and neither Ctrl-C nor
SIGKILL leaves the server or any other process of the pipeline running; a full disk ends it in one line too."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_interrupts import RUN, alive, descendants, wait_for

pytestmark = pytest.mark.slow  # each test starts and stops CLI processes (torch, Warp): in CI, not in a plain make test

ARGV = (
    "pipeline",
    "--task",
    "GalbotG1-PickCube-v0",
    "--demos",
    "2",
    "--mimic-episodes",
    "400",
    "--train-steps",
    "3",
    "--eval-episodes",
    "2",
    "--num-envs",
    "2",
    "--device",
    "cpu",
    "--out",
    "out",
)
"""A pipeline whose Mimic stage runs long after collect has finished."""


def start_pipeline(cwd: Path, *extra: str, write_fault: int | None = None) -> subprocess.Popen:
    """The pipeline in a process of its own, on its embedded server (no user server configured); its stderr in
    ``cwd/stderr.txt`` (a file: a child left alive would hold a pipe open). ``write_fault``: the dataset write of
    that process that the writers' test seam refuses with ENOSPC (armed by the launcher)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_")}
    arm = (
        ""
        if write_fault is None
        else (
            "from newton_lab.datasets.files.write_faults import inject_write_fault; "
            f"inject_write_fault({write_fault}); "
        )
    )
    with open(cwd / "stderr.txt", "w") as err:
        return subprocess.Popen(
            [sys.executable, "-c", arm + RUN, *ARGV, *extra], cwd=cwd, stdout=subprocess.DEVNULL, stderr=err, env=env
        )


def server_of(pid: int) -> list[int]:
    """The pids of ``pid``'s descendants that run uvicorn (the embedded Prefect server)."""
    out = []
    for d in descendants(pid):
        try:
            if b"uvicorn" in Path(f"/proc/{d}/cmdline").read_bytes():
                out.append(d)
        except OSError:
            pass
    return out


def end_all(pids: list[int]) -> float:
    """Seconds until none of ``pids`` runs (then kill what a failed test left running)."""
    start = time.monotonic()
    try:
        wait_for(lambda: not any(alive(p) for p in pids), "the pipeline's processes ending", limit_s=60)
    finally:
        for pid in pids:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
    return time.monotonic() - start


PROGRESS = re.compile(
    r"^(\S+: step \d+, \d+ episodes ended, \d+ successes, \d+ s"
    r"|diffusion policy \S+: (step \d+/\d+, loss .*|\d+ demos, [\d,]+ windows read in .*))$"
)
"""A stage's progress line (collection and Mimic, training; written every few seconds where stderr is not a
terminal)."""
ENDED = re.compile(
    r"newton-lab pipeline: interrupted: finished stages kept in out: (.+); the same command resumes "
    r"from them"
)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_ctrl_c_during_pipeline_keeps_the_finished_stages_in_one_line(tmp_path, signum):
    """SIGINT (SIGTERM) while Mimic runs: exit 130 (143) at once, not after the stage in flight, one line naming the
    finished stage and the folder; the collect stage's manifest and dataset stay (the same command answers it from
    them), Mimic's is not written; the server and the watchdog end."""
    run = start_pipeline(tmp_path)
    manifest = tmp_path / "out" / "demos.manifest.json"
    wait_for(lambda: (manifest.exists() and server_of(run.pid)) or run.poll() is not None, "collect finished")
    assert run.poll() is None, (tmp_path / "stderr.txt").read_text()
    started = descendants(run.pid)
    run.send_signal(signum)
    run.wait(timeout=120)  # the Mimic stage would run for many minutes
    end_all(started)
    lines = [line for line in (tmp_path / "stderr.txt").read_text().splitlines() if line.strip()]
    said = [line for line in lines if not PROGRESS.match(line)]  # the stages' progress lines may come first
    assert run.returncode == 128 + signum and len(said) == 1, lines
    kept = ENDED.fullmatch(said[0])
    assert kept and kept.group(1).split(", ")[0] == "demos", said  # on a loaded machine Mimic may end before
    out = tmp_path / "out"
    assert manifest.exists() and (out / "demos.hdf5").exists()
    for stage in ("mimic", "policy"):  # a finished stage keeps its manifest; the one in flight writes none
        assert (out / f"{stage}.manifest.json").exists() == (stage in kept.group(1).split(", ")), said


@pytest.mark.parametrize("runner", ["local", "dask"])
def test_a_killed_pipeline_leaves_no_process(tmp_path, runner):
    """SIGKILL once the server runs and a stage has begun (local: collect writing; dask: the two worker processes
    up): the server, the Dask workers, the watchdog and anything a stage started end with the pipeline (a watchdog
    on its pid)."""
    dask = ("--runner", "dask", "--workers", "2") if runner == "dask" else ()
    run = start_pipeline(tmp_path, *dask)
    begun = (lambda: len(descendants(run.pid)) >= 4) if dask else (tmp_path / "out" / "demos.hdf5").exists
    wait_for(lambda: server_of(run.pid) and begun() or run.poll() is not None, "the server up and a stage begun")
    assert run.poll() is None, (tmp_path / "stderr.txt").read_text()
    started = descendants(run.pid)
    assert server_of(run.pid)
    run.kill()
    run.wait(timeout=60)
    seconds = end_all(started)
    print(f"{runner}: the pipeline's {len(started)} processes ended {seconds:.2f} s after its SIGKILL")


def test_a_full_disk_ends_the_pipeline_in_one_line(tmp_path):
    """The writer's test seam refuses collect's tenth write with ENOSPC: exit status 1 and one line (Prefect's
    traceback of the failed stage stays off the console); no stage looks finished, and no process is left."""
    run = start_pipeline(tmp_path, write_fault=10)
    started: list[int] = []
    while run.poll() is None:  # the processes it starts, to see them end with it
        started += [p for p in descendants(run.pid) if p not in started]
        time.sleep(0.2)
    end_all(started)
    lines = [line for line in (tmp_path / "stderr.txt").read_text().splitlines() if line.strip()]
    assert run.returncode == 1 and len(lines) == 1, lines
    assert lines[0].startswith("newton-lab pipeline: error: disk full after 0 episodes; ") and "demos.hdf5" in lines[0]
    assert not list((tmp_path / "out").glob("*.manifest.json"))


SLEEPER = "import subprocess, sys, time; {spawn}time.sleep(600)"


def test_the_watchdog_ends_what_a_killed_command_started_and_what_that_started():
    """The watchdog alone, on a plain process: its child and grandchild (sleepers that ignore nothing) end when it is
    killed, and so does the watchdog."""
    grandchild = SLEEPER.format(spawn="")
    child = SLEEPER.format(spawn=f"subprocess.Popen([sys.executable, '-c', {grandchild!r}]); ")
    parent = SLEEPER.format(
        spawn=f"from newton_lab.cli import watchdog; watchdog.start(); "
        f"subprocess.Popen([sys.executable, '-c', {child!r}]); "
    )
    run = subprocess.Popen([sys.executable, "-c", parent])
    wait_for(lambda: len(descendants(run.pid)) >= 3 or run.poll() is not None, "the watchdog, child and grandchild")
    started = descendants(run.pid)
    assert len(started) == 3, started
    run.kill()
    run.wait(timeout=60)
    end_all(started)
