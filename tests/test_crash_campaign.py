"""Crash campaign (issue 16): ``newton-lab collect``, ``mimic``, ``train`` and ``pipeline`` are SIGKILLed at seeded
random moments, then every dataset must read back (info and every demo, finite arrays), the committed episodes never
go down across kills (each run appends to the same dataset), training continues with ``--resume`` from
``resume.pt`` until an uninterrupted resume writes a ``checkpoint.pt`` that loads, and a pipeline re-run completes
with the stages that had finished before the kill reported ``Cached``.

Kill moments are uniform (seed ``NEWTON_LAB_CRASH_SEED``, default 16) inside the command's running window, measured
once by an uninterrupted run: from the moment its first output file appears to its last output line (its summary).
``NEWTON_LAB_CRASH_KILLS`` (default 1, so CI stays short) sets the kills per command; a run that ends (or prints its
summary) before its kill moment counts as a completed run, not as a kill, and the campaign goes on until that many
kills happened (for train, one of them leaving a resume.pt; for the pipeline, one after a finished stage). The whole
process tree is killed (the pipeline's embedded Prefect server with it). ``NEWTON_LAB_CRASH_REPORT=<file>`` writes
the table (kills, episodes lost, corrupt files, resumes completed, wall time) there; it is printed at the end of the
module.

Every run pays Warp/Newton (or Prefect) start-up, so the pipeline campaign runs in a background thread beside the
other three (its processes and theirs share the 2 cores; ``NEWTON_LAB_CRASH_SERIAL=1`` runs it alone, for clean
wall times). The collect campaign's dataset (successful expert demos) is the Mimic source and the training data.
"""

from __future__ import annotations

import json
import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.slow

KILLS = int(os.environ.get("NEWTON_LAB_CRASH_KILLS", "1"))
SEED = int(os.environ.get("NEWTON_LAB_CRASH_SEED", "16"))
TASK = "GalbotG1-PickCube-v0"
CLI = [sys.executable, "-m", "newton_lab.cli"]
SERIAL = os.environ.get("NEWTON_LAB_CRASH_SERIAL", "0") == "1"
RUN_TIMEOUT_S = 600
MAX_RUNS = 3 * KILLS + 6
"""Runs per campaign at most (kills plus runs that ended before their kill moment: a run after warm caches can end
before a moment drawn from the first run's window, more often on a quiet machine)."""

STOP = threading.Event()
"""Set at module teardown: a campaign still running in the background kills its command and stops."""

REPORT: dict[str, dict[str, Any]] = {}
"""command -> its row of the campaign table (filled by each test)."""

COLUMNS = ("command", "kills", "runs", "episodes lost", "corrupt files", "resumes completed", "wall time [s]", "notes")


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: this module runs Warp only in its subprocesses."""
    yield


def table() -> str:
    lines = [
        f"crash campaign: NEWTON_LAB_CRASH_KILLS={KILLS}, NEWTON_LAB_CRASH_SEED={SEED}",
        "| " + " | ".join(COLUMNS) + " |",
        "|" + "---|" * len(COLUMNS),
    ]
    lines += ["| " + " | ".join(str(row.get(c, "")) for c in COLUMNS) + " |" for row in REPORT.values()]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module", autouse=True)
def _table(request):
    yield
    if REPORT:
        capture = request.config.pluginmanager.getplugin("capturemanager")
        with capture.global_and_fixture_disabled():
            print("\n" + table())


# --- running and killing a command ------------------------------------------------------------------------------


class Run:
    """One command run: exit code, whether it was killed, wall time, when its first output appeared, its log."""

    def __init__(self, argv: list[str], log: Path) -> None:
        self.argv, self.log = argv, log
        self.rc: int | None = None
        self.killed = False
        self.killed_after_summary = False
        self.wall_s = 0.0
        self.first_output_s: float | None = None
        self.last_output_s = 0.0

    @property
    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def tail(self, n: int = 25) -> str:
        return "\n".join(self.text.splitlines()[-n:])

    def last_json(self) -> dict[str, Any]:
        lines = [ln for ln in self.text.splitlines() if ln.startswith("{")]
        assert lines, f"{' '.join(self.argv)} printed no JSON summary:\n{self.tail()}"
        return json.loads(lines[-1])


def _env() -> dict[str, str]:
    """The user's environment without Prefect settings (the pipeline keeps its state under --out) and with Prefect's
    task-run log lines on (they say which stages finished before a kill); one torch thread beside another campaign."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_")}
    env.update(PYTHONUNBUFFERED="1", PREFECT_LOGGING_LEVEL="INFO")
    if not SERIAL:  # two campaigns at once: two torch trainings with a thread pool each would thrash the 2 cores
        env.update(OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    return env


def _descendants(pid: int) -> list[int]:
    children: dict[int, list[int]] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in ("Z", "X")


def _kill_tree(proc: subprocess.Popen) -> None:
    """SIGKILL the command, then every process it started (each by its id), as a crash of the machine would."""
    tree = _descendants(proc.pid)
    proc.kill()
    for pid in tree:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.wait()
    deadline = time.monotonic() + 10
    while any(_alive(pid) for pid in tree) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(pid) for pid in tree), f"processes {tree} outlived SIGKILL"


def run_cli(
    args: list[str], log: Path, *, kill_at: float | None = None, first_output: Callable[[], bool] | None = None
) -> Run:
    """Run ``newton-lab <args>`` (output to ``log``); SIGKILL its process tree ``kill_at`` seconds after the start
    unless it ended before. A kill after the command printed its JSON summary is no kill (the run completed)."""
    run = Run(args, log)
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [*CLI, *args], cwd=log.parent, env=_env(), stdout=out, stderr=subprocess.STDOUT, start_new_session=True
        )
    t0, t0_wall = time.monotonic(), time.time()
    try:
        while True:
            now = time.monotonic() - t0
            if first_output is not None and run.first_output_s is None and first_output():
                run.first_output_s = now
            if proc.poll() is not None:
                break
            if kill_at is not None and now >= kill_at:
                _kill_tree(proc)
                run.killed = True
                break
            if now > RUN_TIMEOUT_S or STOP.is_set():
                _kill_tree(proc)
                raise AssertionError(
                    f"newton-lab {' '.join(args)} ran over {RUN_TIMEOUT_S} s or was stopped:\n{run.tail()}"
                )
            time.sleep(0.02)
    finally:
        if proc.poll() is None:  # an error in this loop: leave nothing running
            _kill_tree(proc)
    run.wall_s = time.monotonic() - t0
    run.last_output_s = min(log.stat().st_mtime - t0_wall, run.wall_s)
    run.rc = proc.returncode
    if run.killed and any(line.startswith("{") for line in run.text.splitlines()):
        run.killed, run.killed_after_summary = False, True  # its work was done: a completed run
    return run


def finished(run: Run) -> Run:
    """``run``, which must have completed (exit 0, or killed while exiting after its summary line)."""
    assert run.rc == 0 or run.killed_after_summary, f"newton-lab {' '.join(run.argv)} exited {run.rc}:\n{run.tail()}"
    return run


def running_window(measure: Run) -> tuple[float, float]:
    """From the first output (a file appeared) to the last (the summary line; after it the process only exits)."""
    window = (measure.first_output_s or 0.0, measure.last_output_s)
    assert window[1] > window[0] >= 0, f"bad measured window {window} of {' '.join(measure.argv)}"
    return window


def narrowed(window: tuple[float, float], run: Run) -> tuple[float, float]:
    """``window`` scaled to a run that completed before its kill moment. The measured run can be much slower than
    later ones (on a cold Warp cache it compiles the kernels), so later kill moments follow the latest run."""
    if run.killed or run.last_output_s >= window[1]:
        return window
    scale = run.last_output_s / window[1]
    return window[0] * scale, run.last_output_s


def kill_moments(command: str) -> random.Random:
    """The seeded generator of ``command``'s kill moments (draw with ``rng.uniform(*window)``)."""
    return random.Random(f"{SEED}/{command}")


def row(command: str, **values: Any) -> dict[str, Any]:
    """Record ``command``'s row of the table (keyword names are the columns with ``_`` for spaces, ``_s`` for [s])."""
    names = {c.replace(" [s]", "_s").replace(" ", "_"): c for c in COLUMNS}
    REPORT[command] = {"command": command, **{names[k]: v for k, v in values.items()}}
    if os.environ.get("NEWTON_LAB_CRASH_REPORT"):  # written as each campaign ends: a cut-short session keeps its rows
        Path(os.environ["NEWTON_LAB_CRASH_REPORT"]).write_text(table())
    return REPORT[command]


# --- checking what a killed run left --------------------------------------------------------------------------


def _arrays(tree: dict[str, Any]):
    for key, value in tree.items():
        if isinstance(value, dict):
            yield from _arrays(value)
        elif isinstance(value, np.ndarray):
            yield key, value


def read_all(path: Path) -> tuple[list[int], list[str]]:
    """(committed demo ids, problems): the dataset's info and every demo read back, with each demo's frame count
    and finite values checked."""
    from newton_lab.datasets import read_dataset_info, read_episode  # deferred: imports Warp/Newton

    try:
        info = read_dataset_info(path)
    except Exception as exc:  # noqa: BLE001 - any failure to read is what this campaign looks for
        return [], [f"{path}: {type(exc).__name__}: {exc}"]
    problems = []
    for demo in info["demo_ids"]:
        try:
            ep = read_episode(path, demo)
            n = info["demos"][demo]["num_samples"]
            if ep["actions"].shape[0] != n or ep["attrs"]["num_samples"] != n:
                problems.append(f"{path} demo {demo}: {ep['actions'].shape[0]} action rows, {n} samples")
            bad = [k for k, a in _arrays(ep) if a.dtype.kind == "f" and not np.isfinite(a).all()]
            if bad:
                problems.append(f"{path} demo {demo}: non-finite {bad}")
        except Exception as exc:  # noqa: BLE001
            problems.append(f"{path} demo {demo}: {type(exc).__name__}: {exc}")
    return list(info["demo_ids"]), problems


# --- collect and mimic: append runs on one dataset ------------------------------------------------------------


def append_campaign(
    command: str, args: list[str], path: Path, folder: Path, added: Callable[[Run], int]
) -> dict[str, Any]:
    """Measure one uninterrupted run, kill runs at seeded moments (every run appends to ``path``), then one
    uninterrupted run. After each run every demo must read back and no committed demo may be gone; a run that
    completes appends exactly what it reports."""
    t_start = time.monotonic()
    measure = finished(run_cli(args, folder / "run0.log", first_output=path.exists))
    ids, corrupt = read_all(path)
    assert len(ids) == added(measure), f"{command}: {len(ids)} demos after a run that reported {added(measure)}"
    window = running_window(measure)
    rng = kill_moments(command)
    kills = runs = 0
    gone: list[int] = []
    committed_by_killed: list[int] = []  # demos each killed run had committed (of the measured run's {added})
    appends_after_kill = 0
    while True:
        final = kills >= KILLS
        assert runs < MAX_RUNS, f"{command}: only {kills} of {KILLS} runs could be killed in {runs} runs"
        runs += 1
        run = run_cli(args, folder / f"run{runs}.log", kill_at=None if final else rng.uniform(*window))
        now, problems = read_all(path)
        corrupt += problems
        gone += sorted(set(ids) - set(now))
        if run.killed:
            kills += 1
            committed_by_killed.append(len(now) - len(ids))
        else:
            assert len(now) == len(ids) + added(finished(run)), f"{command} run {runs} did not append all it reported"
            appends_after_kill += kills > 0
            window = narrowed(window, run)
        ids = now
        if final:
            break
    row(
        command,
        kills=kills,
        runs=runs + 1,
        episodes_lost=len(gone),
        corrupt_files=len(corrupt),
        resumes_completed=f"{appends_after_kill} appending runs",
        wall_time_s=round(time.monotonic() - t_start, 1),
        notes=f"demos committed by the killed runs (of {added(measure)}): {committed_by_killed}",
    )
    return {
        "path": path,
        "kills": kills,
        "gone": gone,
        "corrupt": corrupt,
        "demos": len(ids),
        "appends_after_kill": appends_after_kill,
    }


@pytest.fixture(scope="module")
def collected(tmp_path_factory) -> dict[str, Any]:
    """The collect campaign on an HDF5 dataset (full-length expert episodes: the Mimic source and training data)."""
    folder = tmp_path_factory.mktemp("crash_collect")
    path = folder / "demos.hdf5"
    args = [
        "collect",
        "--task",
        TASK,
        "--num-envs",
        "2",
        "--episodes",
        "4",
        "--max-steps",
        "300",
        "--seed",
        "0",
        "--randomize",
        "--no-progress",
        "--cameras",
        "none",
        "--dataset-path",
        str(path),
    ]
    return append_campaign("collect", args, path, folder, added=lambda run: run.last_json()["episodes"])


def assert_nothing_lost(result: dict[str, Any]) -> None:
    assert result["kills"] == KILLS
    assert not result["gone"], f"committed demos gone after a kill: {result['gone']}"
    assert not result["corrupt"], f"damaged after kills: {result['corrupt'][:5]}"
    assert result["appends_after_kill"] >= 1, "no run appended to the dataset after a kill"


def test_collect_survives_sigkill(collected):
    assert_nothing_lost(collected)


def test_mimic_survives_sigkill(collected, tmp_path):
    path = tmp_path / "mimic.zarr"  # the zarr writer (collect covers HDF5)
    args = [
        "mimic",
        "--dataset-path",
        str(collected["path"]),
        "--output-path",
        str(path),
        "--episodes",
        "4",
        "--num-envs",
        "2",
        "--seed",
        "1",
        "--no-progress",
    ]
    assert_nothing_lost(append_campaign("mimic", args, path, tmp_path, added=lambda run: run.last_json()["successes"]))


# --- train: resume from resume.pt -------------------------------------------------------------------------------

TRAIN_STEPS = 40


def train_args(source: Path, out: Path) -> list[str]:
    return [
        "train",
        "--dataset-path",
        str(source),
        "--output-dir",
        str(out),
        "--preset",
        "cpu",
        "--max-steps",
        str(TRAIN_STEPS),
        "--batch-size",
        "32",
        "--checkpoint-every-steps",
        "4",
        "--seed",
        "0",
    ]


def check_trained(out: Path, checkpoint: Path, resumed_from: list[int]) -> bool:
    """The finished run of ``out``: its checkpoint loads, ran every step, and lists only resumes from resume files
    seen after the kills (the last one among them). True if it was a resumed run."""
    from newton_lab.policies import DiffusionPolicy  # deferred: torch is slow to import

    assert not (out / "resume.pt").exists(), f"{out}: the finished run left its resume.pt"
    assert not list(out.glob(".resume.pt.*.tmp")), f"{out}: temporary resume files left"
    training = DiffusionPolicy.load(checkpoint).info["training"]
    assert training["steps"] == TRAIN_STEPS
    at = training["resumed_at_steps"]
    assert at == sorted(set(at)) and set(at) <= set(resumed_from), (at, resumed_from)
    return bool(at)


def test_train_resumes_after_sigkill(collected, tmp_path):
    import torch  # deferred: torch is slow to import

    source = collected["path"]
    t_start = time.monotonic()
    measured = tmp_path / "measured"
    measure = finished(
        run_cli(train_args(source, measured), tmp_path / "measure.log", first_output=(measured / "resume.pt").exists)
    )
    check_trained(measured, measured / "checkpoint.pt", [])
    window = running_window(measure)
    rng = kill_moments("train")
    kills = runs = cycle = resumes_completed = resumed_runs = kills_leaving_resume = 0
    leftovers: list[str] = []
    out, steps_seen = tmp_path / "run0", []  # resume steps found after the kills of the running cycle
    while True:
        final = kills >= KILLS and kills_leaving_resume > 0  # at least one kill must leave a run to resume
        resume = (out / "resume.pt").exists()
        if final and not resume:
            break
        assert runs < MAX_RUNS, f"train: only {kills} of {KILLS} runs could be killed in {runs} runs"
        runs += 1
        resumed_runs += resume
        run = run_cli(
            train_args(source, out) + ["--resume"] * resume,
            tmp_path / f"run{runs}.log",
            kill_at=None if final else rng.uniform(*window),
        )
        kills += run.killed
        if not resume:  # a resumed run skips the steps done before: it says nothing about a fresh run's length
            window = narrowed(window, run)
        if not run.killed:
            checkpoint = Path(finished(run).last_json()["checkpoint"])
        elif not (out / "resume.pt").exists() and (out / "checkpoint.pt").exists():
            checkpoint = out / "checkpoint.pt"  # killed after the run had written its final checkpoint
        else:
            checkpoint = None
        if checkpoint is not None:  # the cycle is over
            resumes_completed += check_trained(out, checkpoint, steps_seen)
            leftovers += [str(p.relative_to(tmp_path)) for p in out.glob(".*.tmp")]
            if checkpoint.name != "checkpoint.pt":  # a kill between the final checkpoint and removing resume.pt
                leftovers.append(f"{checkpoint.relative_to(tmp_path)} beside an earlier checkpoint.pt")
            cycle += 1
            out, steps_seen = tmp_path / f"run{cycle}", []
            continue
        if (out / "resume.pt").exists():
            state = torch.load(out / "resume.pt", map_location="cpu", weights_only=True)  # atomic: never torn
            step = state["progress"]["step"]
            assert 0 < step < TRAIN_STEPS and step >= max(steps_seen, default=0), (step, steps_seen)
            steps_seen.append(step)
            kills_leaving_resume += 1
        else:
            assert not resume, f"{out}: a resumed run killed at {run.wall_s:.1f} s lost its resume.pt"
    assert kills >= KILLS and resumes_completed >= 1, "no run continued from a resume.pt to its end"
    row(
        "train",
        kills=kills,
        runs=runs + 1,
        episodes_lost=0,
        corrupt_files=0,
        resumes_completed=f"{resumes_completed} of {resumed_runs} resumed runs",
        wall_time_s=round(time.monotonic() - t_start, 1),
        notes=", ".join(leftovers),
    )


# --- pipeline: re-run after kills --------------------------------------------------------------------------------

STAGES = ("collect", "mimic", "train", "evaluate")
FINISHED = re.compile(r"Task run '(collect|mimic|merge|train|evaluate)-[^']*' - Finished in state (\w+)\(")
MANIFESTS = {"demos": "collect", "mimic": "mimic", "policy": "train"}


def pipeline_args(out: Path) -> list[str]:
    return [
        "pipeline",
        "--task",
        TASK,
        "--demos",
        "2",
        "--mimic-episodes",
        "2",
        "--train-steps",
        "20",
        "--eval-episodes",
        "2",
        "--num-envs",
        "2",
        "--device",
        "cpu",
        "--out",
        str(out),
    ]


def stages_finished(run: Run) -> dict[str, str]:
    """stage -> the state it finished in, as the run logged it (Prefect logs it after the result is written)."""
    return dict(FINISHED.findall(run.text))


def check_artifacts(out: Path) -> tuple[int, list[str]]:
    """(episodes lost, problems) of the pipeline's finished artifacts (those with a manifest) and of any dataset
    an interrupted stage left (the re-run replaces it, but it must read back)."""
    from newton_lab.policies import DiffusionPolicy  # deferred: torch is slow to import

    lost, problems = 0, []
    for name in MANIFESTS:
        manifest = out / f"{name}.manifest.json"
        if not manifest.exists():
            if (out / f"{name}.hdf5").exists():
                problems += read_all(out / f"{name}.hdf5")[1]
            continue
        art = json.loads(manifest.read_text())["artifact"]
        if name == "policy":
            try:
                DiffusionPolicy.load(art["path"])
            except Exception as exc:  # noqa: BLE001
                problems.append(f"{art['path']}: {type(exc).__name__}: {exc}")
            continue
        ids, bad = read_all(Path(art["path"]))
        problems += bad
        lost += max(0, art["metrics"]["episodes"] - len(ids))
    return lost, problems


def pipeline_campaign(folder: Path) -> dict[str, Any]:
    """Measure one uninterrupted pipeline, then kill runs at seeded moments; each killed run's --out is run again
    (killed again, or to its end) until it completes. Stages a killed run had finished must come back ``Cached``
    (in the log of every later run that reaches them, and in the completed run's ``stage_states``)."""
    t_start = time.monotonic()
    measured = folder / "measured"
    measure = finished(
        run_cli(pipeline_args(measured), folder / "measure.log", first_output=(measured / "demos.hdf5").exists)
    )
    states = json.loads((measured / "metrics.json").read_text())["stage_states"]
    assert states == {s: ["Completed"] for s in STAGES}, states
    assert (measured / ".prefect").is_dir(), "the embedded Prefect server's state must live under --out"
    window = running_window(measure)
    rng = kill_moments("pipeline")
    kills = runs = cycle = cycle_kills = lost = kills_after_a_stage = 0
    corrupt: list[str] = []
    recomputed: list[str] = []
    reruns: list[dict[str, list[str]]] = []  # stage_states of the re-runs that completed after kills
    out, done_before = folder / "run0", set()  # stages that finished in a killed run of this --out
    while True:
        final = kills >= KILLS and kills_after_a_stage > 0  # at least one kill must come after a finished stage
        if final and not cycle_kills:
            break
        assert runs < MAX_RUNS, f"pipeline: only {kills} of {KILLS} runs could be killed in {runs} runs"
        runs += 1
        run = run_cli(pipeline_args(out), folder / f"run{runs}.log", kill_at=None if final else rng.uniform(*window))
        logged = stages_finished(run)
        recomputed += [
            f"run {runs}: {s} {logged[s]}" for s in sorted(done_before & logged.keys()) if logged[s] != "Cached"
        ]
        n, problems = check_artifacts(out)
        lost, corrupt = lost + n, corrupt + problems
        if run.killed:
            kills += 1
            cycle_kills += 1
            done_before |= {s for s, state in logged.items() if state in ("Completed", "Cached")}
            kills_after_a_stage += bool(done_before)
            continue
        finished(run)
        if not cycle_kills:  # a re-run answers finished stages from the cache: shorter than a fresh run
            window = narrowed(window, run)
        states = json.loads((out / "metrics.json").read_text())["stage_states"]
        assert set(states) == set(STAGES) and all(v[-1] in ("Completed", "Cached") for v in states.values()), states
        recomputed += [f"run {runs}: {s} {states[s]}" for s in sorted(done_before) if states[s] != ["Cached"]]
        assert (out / ".prefect").is_dir(), "the embedded Prefect server's state must live under --out"
        if cycle_kills:
            reruns.append({"states": states, "cached": sorted(done_before)})
        cycle += 1
        out, done_before, cycle_kills = folder / f"run{cycle}", set(), 0
    row(
        "pipeline",
        kills=kills,
        runs=runs + 1,
        episodes_lost=lost,
        corrupt_files=len(corrupt),
        resumes_completed=f"{len(reruns)} re-runs ({sum(len(r['cached']) for r in reruns)} stages Cached)",
        wall_time_s=round(time.monotonic() - t_start, 1),
        notes="; ".join(recomputed),
    )
    return {"kills": kills, "lost": lost, "corrupt": corrupt, "recomputed": recomputed, "reruns": reruns}


@pytest.fixture(scope="module")
def pipeline_lane(tmp_path_factory):
    """The pipeline campaign, running in a background thread from the first time this fixture is asked for."""
    pool = ThreadPoolExecutor(1, thread_name_prefix="crash-pipeline")
    future = pool.submit(pipeline_campaign, tmp_path_factory.mktemp("crash_pipeline"))
    yield future
    STOP.set()  # the module is over (or was interrupted): a campaign still running kills its command
    pool.shutdown(wait=True)


@pytest.fixture(scope="module", autouse=True)
def _pipeline_in_background(request):
    """Start the pipeline campaign with the module's first test when it is selected (not with --serial)."""
    if not SERIAL and any(
        item.name == "test_pipeline_rerun_after_sigkill_uses_the_cache" for item in request.session.items
    ):
        request.getfixturevalue("pipeline_lane")
    yield


def test_pipeline_rerun_after_sigkill_uses_the_cache(pipeline_lane: Future):
    result = pipeline_lane.result()
    assert result["kills"] >= KILLS
    assert not result["lost"] and not result["corrupt"], (result["lost"], result["corrupt"][:5])
    assert not result["recomputed"], f"stages finished before a kill were computed again: {result['recomputed']}"
    assert any(r["cached"] for r in result["reruns"]), "no re-run after a kill completed with a cached stage"
