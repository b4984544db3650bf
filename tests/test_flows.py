"""The Prefect pipeline end to end at tiny sizes on the local runner, read back through the Prefect API.

One pipeline run serves the module: its train stage hits a transient I/O error on the first try (the stage
fault seam) and is retried; its stage logs are shipped to the test server. The re-run is answered from the
cache; an input error fails at once, is not retried and prints one line.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from newton_lab.flows import settings
from newton_lab.flows.runlog import ARTIFACT_KEYS
from newton_lab.flows.stages import _finish, _guard
from stage_faults import SPEC_ENV as FAULT_ENV, armed

pytestmark = pytest.mark.slow

TINY_TRAIN = {
    "down_dims": [16, 32, 64],
    "batch_size": 32,
    "max_steps": 3,
    "epochs": 1,
    "warmup_steps": 1,
    "progress": False,
}
TINY = dict(
    task_id="GalbotG1-PickCube-v0",
    demos=2,
    mimic_episodes=2,
    train_cfg=TINY_TRAIN,
    eval_episodes=2,
    num_envs=2,
    device="cpu",
    eval_max_steps=10,
)
TINY_CLI = [
    "--task",
    "GalbotG1-PickCube-v0",
    "--demos",
    "2",
    "--mimic-episodes",
    "2",
    "--train-steps",
    "3",
    "--eval-episodes",
    "2",
    "--num-envs",
    "2",
    "--device",
    "cpu",
]
STAGES = ("collect", "mimic", "train", "evaluate")
RETRY_STATES = {"AwaitingRetry", "Retrying"}


@pytest.fixture(scope="module")
def harness(tmp_path_factory):
    settings.configure(tmp_path_factory.mktemp("prefect_home"))
    from prefect.testing.utilities import prefect_test_harness  # deferred: Prefect reads settings.configure's home

    with prefect_test_harness(server_startup_timeout=120):
        yield


# ----------------------------------------------------------------------------- reading the Prefect API
def task_runs(flow_run_id) -> dict[str, list[tuple[Any, list[str]]]]:
    """stage name -> [(task run, its state history names)] of a flow run. The server records task runs from
    the events the engine sends, so this waits (up to a minute) until every task run it lists is final."""
    from prefect import get_client  # deferred: Prefect must follow settings.configure()
    from prefect.client.schemas.filters import FlowRunFilter, FlowRunFilterId

    with get_client(sync_client=True) as client:
        deadline = time.monotonic() + 60
        while True:
            runs = client.read_task_runs(flow_run_filter=FlowRunFilter(id=FlowRunFilterId(any_=[flow_run_id])))
            if (runs and all(r.state is not None and r.state.is_final() for r in runs)) or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        found: dict[str, list[tuple[Any, list[str]]]] = {}
        for r in runs:
            found.setdefault(r.name.rsplit("-", 1)[0], []).append(
                (r, [s.name for s in client.read_task_run_states(r.id)])
            )
    return found


def artifacts(flow_run_id) -> dict[str, Any]:
    """key -> data of the artifacts a flow run published (tables decoded from JSON)."""
    from prefect import get_client  # deferred: Prefect must follow settings.configure()
    from prefect.client.schemas.filters import ArtifactFilter, ArtifactFilterFlowRunId

    with get_client(sync_client=True) as client:
        arts = client.read_artifacts(
            artifact_filter=ArtifactFilter(flow_run_id=ArtifactFilterFlowRunId(any_=[flow_run_id]))
        )
    return {a.key: json.loads(a.data) if a.type == "table" and isinstance(a.data, str) else a.data for a in arts}


def logs(flow_run_id, until: str) -> list[Any]:
    """Log records stored for a flow run and its task runs; waits (up to a minute) for one containing ``until``
    (the engine ships logs in batches)."""
    from prefect import get_client  # deferred: Prefect must follow settings.configure()
    from prefect.client.schemas.filters import LogFilter, LogFilterFlowRunId

    with get_client(sync_client=True) as client:
        deadline = time.monotonic() + 60
        while True:
            found = client.read_logs(log_filter=LogFilter(flow_run_id=LogFilterFlowRunId(any_=[flow_run_id])))
            if any(until in r.message for r in found) or time.monotonic() > deadline:
                return found
            time.sleep(0.5)


def latest_flow_run(out: Path):
    """The newest pipeline flow run whose ``out`` parameter is ``out``."""
    from prefect import get_client  # deferred: Prefect must follow settings.configure()
    from prefect.client.schemas.sorting import FlowRunSort

    with get_client(sync_client=True) as client:
        runs = client.read_flow_runs(sort=FlowRunSort.EXPECTED_START_TIME_DESC, limit=50)
    return next(r for r in runs if r.parameters.get("out") == str(out))


def run_cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """``newton-lab`` in a child process against the test server (as a user's own server: logs shipped)."""
    from prefect.settings import PREFECT_API_URL  # deferred: Prefect must follow settings.configure()

    env = {**os.environ, "PREFECT_API_URL": PREFECT_API_URL.value()}
    for key in (FAULT_ENV, "PREFECT_LOGGING_TO_API_ENABLED"):  # a user server ships logs
        env.pop(key, None)
    return subprocess.run(
        [sys.executable, "-m", "newton_lab.cli", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


def error_lines(stderr: str) -> list[str]:
    """stderr without Warp's CUDA-driver notice and start-up banner (printed on hosts without a GPU)."""
    return [
        line
        for line in stderr.splitlines()
        if line.strip() and not line.startswith(("Warp ", "   ")) and "Kernel cache" not in line
    ]


def stale_manifest(folder: Path, name: str = "demos") -> None:
    """Make ``folder`` look like another pipeline's output (its collect stage then refuses it: an input error)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "x").write_text("x")
    _finish(folder, name, {"task_id": "another"}, {"path": str(folder / "x")})


def assert_input_error_reported_once(proc: subprocess.CompletedProcess, out: Path, shards: int) -> None:
    """Exit 2, one stderr line, no traceback; every collect task run failed on its first and only try."""
    lines = error_lines(proc.stderr)
    assert proc.returncode == 2, proc.stderr[-3000:]
    assert lines == [lines[0]] and lines[0].startswith("newton-lab pipeline: error:"), proc.stderr[-3000:]
    assert "another pipeline's demos" in lines[0] and "Traceback" not in proc.stderr + proc.stdout
    runs = task_runs(latest_flow_run(out).id)
    assert len(runs["collect"]) == shards and set(runs) == {"collect"}, runs
    for run, history in runs["collect"]:
        assert run.state_name == "Failed" and run.run_count == 1 and not RETRY_STATES & set(history), history


# ----------------------------------------------------------------------------- one pipeline run
@pytest.fixture(scope="module")
def run(harness, tmp_path_factory):
    """The tiny pipeline, logs shipped to the test server; its train stage fails once with an I/O error."""
    from newton_lab.flows import pipeline  # deferred: imports Prefect (after the harness configured it)
    from prefect.settings import PREFECT_LOGGING_TO_API_ENABLED, temporary_settings  # deferred: after configure

    tmp = tmp_path_factory.mktemp("pipeline")
    with armed(f"train:oserror:{tmp / 'train.fault'}"), temporary_settings({PREFECT_LOGGING_TO_API_ENABLED: True}):
        state = pipeline(out=str(tmp / "out"), return_state=True, **TINY)
    return {
        "out": tmp / "out",
        "fault": tmp / "train.fault",
        "summary": state.result(),
        "id": state.state_details.flow_run_id,
    }


def test_pipeline_runs_then_is_cached(run):
    from newton_lab.flows import pipeline  # deferred: imports Prefect (after the harness configured it)

    first, out = run["summary"], run["out"]
    assert set(first["artifacts"]) == {"demos", "mimic", "checkpoint"}
    assert first["evaluation"]["episodes"] == 2 and 0.0 <= first["success_rate"] <= 1.0
    assert json.loads((out / "metrics.json").read_text())["task"] == "GalbotG1-PickCube-v0"
    rec = Path(first["evaluation"]["recording"])  # two evaluation episodes, for the viewer
    assert rec == out / "evaluation.rrd" and rec.stat().st_size > 0
    assert first["stage_states"] == {s: ["Completed"] for s in STAGES}
    record = json.loads(Path(first["record"]).read_text())  # the run record: what ran, where, what it measured
    assert Path(first["record"]).parent == out / "records" and record["kind"] == "pipeline"
    assert record["task"] == "GalbotG1-PickCube-v0" and record["device"]["kind"] == "cpu"
    res = record["results"]
    assert res["success"]["episodes"] == 2 and res["success"]["eval_seed"] == TINY.get("seed", 0) + 10_000
    assert res["counts"]["expert_demos"] == 2 and res["counts"]["mimic_demos"] == 2
    assert set(res["timings_s"]) == {*STAGES, "flow"} and res["stage_states"] == first["stage_states"]
    second = pipeline(out=str(out), **TINY)
    assert second["artifacts"] == first["artifacts"]
    assert second["stage_states"] == {s: ["Cached"] for s in STAGES}  # the re-run computed nothing
    assert second["record"] != first["record"] and Path(first["record"]).is_file()  # a record of its own


def test_transient_error_is_retried(run):
    runs = task_runs(run["id"])
    assert run["fault"].exists(), "the fault seam did not fire"
    assert set(runs) == set(STAGES) and all(len(v) == 1 for v in runs.values()), runs
    ((train, history),) = runs["train"]
    assert train.state_name == "Completed" and train.run_count == 2 and RETRY_STATES <= set(history), history
    for stage in ("collect", "mimic", "evaluate"):
        ((other, history),) = runs[stage]
        assert other.run_count == 1 and not RETRY_STATES & set(history), (stage, history)


def test_each_stage_publishes_its_artifact(run):
    arts = artifacts(run["id"])
    assert set(arts) == set(ARTIFACT_KEYS.values())
    demos = {r["field"]: r["value"] for r in arts["collect-dataset"]}
    assert demos["episodes"] == "2" and int(demos["samples"]) > 0
    assert demos["path"] == run["summary"]["artifacts"]["demos"]["path"]
    mimic = {r["field"]: r["value"] for r in arts["mimic-dataset"]}
    assert mimic["episodes"] == "2" and mimic["generation rate"].endswith("%")
    curve = arts["train-loss-curve"]
    assert curve and curve[-1]["steps"] == 3 and all(r["loss"] > 0 for r in curve)
    evaluation = {r["metric"]: r["value"] for r in arts["evaluation"]}
    assert evaluation["episodes"] == "2" and any(k.startswith("termination: ") for k in evaluation)
    assert "evaluation success rate" in arts["newton-lab-pipeline"]


def test_stage_logs_are_stored(run):
    records = logs(run["id"], until="evaluate: done in")
    runs = task_runs(run["id"])
    by_run = {stage: [r.message for r in records if r.task_run_id == runs[stage][0][0].id] for stage in STAGES}
    for stage in STAGES:
        assert any(m.startswith(f"{stage}: done in") for m in by_run[stage]), (stage, by_run[stage])
    assert any(m.startswith("train: epoch 1: step 3, loss") for m in by_run["train"])
    assert any("injected transient I/O error" in m and "Retry 1/1" in m for m in by_run["train"])


def test_input_error_is_not_retried_and_prints_one_line(harness, tmp_path):
    out = tmp_path / "out"
    stale_manifest(out)
    proc = run_cli(["pipeline", *TINY_CLI, "--out", str(out)], tmp_path)
    assert_input_error_reported_once(proc, out, shards=1)
    # on a user's own server (PREFECT_API_URL set) the run logs are shipped by default: the UI shows the error
    flow_run = latest_flow_run(out)
    records = logs(flow_run.id, until="another pipeline's demos")
    assert any("ValueError" in r.message and r.task_run_id is not None for r in records), records


# ----------------------------------------------------------------------------- inputs checked up front
def test_pipeline_counts_are_checked_before_anything_runs(tmp_path):
    from newton_lab.flows.orchestration import run_pipeline  # deferred: Prefect is slow to import

    for name in ("demos", "mimic_episodes", "eval_episodes"):
        with pytest.raises(ValueError, match=f"{name} must be an integer >= 1"):
            run_pipeline(**{**TINY, name: 0, "out": str(tmp_path / name)})
        assert not (tmp_path / name).exists()


def test_bad_pipeline_inputs():
    from newton_lab.flows.orchestration import run_pipeline  # deferred: Prefect is slow to import

    with pytest.raises(ValueError, match="unknown runner"):
        run_pipeline(runner="ray", task_id="GalbotG1-PickCube-v0")
    with pytest.raises(ValueError, match="workers"):
        run_pipeline(runner="dask", workers=0, task_id="GalbotG1-PickCube-v0")
    with pytest.raises(ValueError, match="unknown task id"):
        run_pipeline(task_id="GalbotG1-Nope-v0")
    with pytest.raises(ConnectionError, match="unreachable"):
        run_pipeline(runner="dask", workers=2, address="tcp://127.0.0.1:1", task_id="GalbotG1-PickCube-v0")


def test_output_folder_of_another_pipeline_is_refused(tmp_path):
    (tmp_path / "x").write_text("x")
    _finish(tmp_path, "demos", {"task_id": "A"}, {"path": str(tmp_path / "x")})
    with pytest.raises(ValueError, match="another pipeline"):
        _guard(tmp_path, "demos", {"task_id": "B"})


def test_console_leaves_failures_to_the_caller():
    """Prefect's console handler drops flow tracebacks, the tracebacks of input errors and of writes the disk
    refused, and 'Finished in state Failed' lines (the caller reports them once, in one line); a stage's other errors
    and every other record still print."""
    import logging

    from newton_lab.flows.orchestration import REPORTED_ERRORS  # deferred: Prefect is slow to import
    from newton_lab.flows.runlog import CallerReports

    from newton_lab.datasets import DatasetWriteError

    def record(name, msg, exc=None):
        return logging.LogRecord(name, logging.ERROR, __file__, 1, msg, None, (type(exc), exc, None) if exc else None)

    keep = CallerReports(REPORTED_ERRORS).filter
    assert not keep(record("prefect.flow_runs", "Encountered exception", RuntimeError("x")))
    assert not keep(record("prefect.task_runs", "Task run failed", ValueError("bad input")))
    assert not keep(record("prefect.task_runs", "Task run failed", DatasetWriteError("disk full after 1 episode", 28)))
    assert not keep(record("prefect.task_runs", "Finished in state Failed('x')"))
    assert keep(record("prefect.task_runs", "Task run failed", OSError("disk")))
    assert keep(record("prefect.task_runs", "train: done in 3.0 s"))
    assert keep(record("prefect.flow_runs", "mimic run 1 of 2: its Dask worker died 1 time(s)"))
    assert keep(record("distributed.nanny", "Finished in state Failed", ValueError("x")))


def test_pipeline_without_rerun_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """On a host without rerun-sdk, ``pipeline`` (which records its evaluation by default) is refused in one line
    that names --no-record, before anything is collected or written; a plan (--dry-run) still prints."""
    import sys

    from newton_lab.cli import main

    monkeypatch.setitem(sys.modules, "rerun", None)  # how Python marks a package it cannot import
    out = tmp_path / "run"
    assert main(["pipeline", "--task", "GalbotG1-PickCube-v0", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "rerun-sdk is not installed here" in err and "--no-record" in err
    assert not out.exists()
    assert main(["pipeline", "--task", "GalbotG1-PickCube-v0", "--out", str(out), "--dry-run"]) == 0
