"""The whole pipeline on a local Dask cluster of 2 worker processes (``--runner dask --workers 2``) at tiny sizes.

One run serves the module; on its way a collect shard hits a transient I/O error (Prefect retries it) and a
Mimic shard's worker process is SIGKILLed (Dask re-runs the shard on a live worker): it must still complete,
with both retries recorded. An input error on Dask fails at once, is not retried and prints one line.
"""

from __future__ import annotations

import inspect
import json
import socket

import pytest
from newton_lab.flows.cluster import NANNY_CLOSE_S, SCHEDULER_HTTP, cluster_options, visible_gpus
from stage_faults import armed
from test_flows import (  # noqa: F401
    ARTIFACT_KEYS,
    RETRY_STATES,
    TINY,
    TINY_CLI,
    artifacts,
    assert_input_error_reported_once,
    harness,
    run_cli,
    stale_manifest,
    task_runs,
)

from newton_lab.datasets import read_dataset_info, read_episode

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def dask_run(harness, tmp_path_factory):
    from newton_lab.flows.orchestration import run_pipeline  # deferred: imports Prefect (after the harness)

    tmp = tmp_path_factory.mktemp("dask")
    with armed(f"collect:oserror:{tmp / 'collect.fault'},mimic:kill:{tmp / 'mimic.fault'}", dask_workers=True):
        state = run_pipeline(runner="dask", workers=2, out=str(tmp / "out"), return_state=True, **TINY)
    return {"out": tmp / "out", "tmp": tmp, "summary": state.result(), "id": state.state_details.flow_run_id}


def test_pipeline_runs_on_dask(dask_run):
    summary = dask_run["summary"]
    states = summary["stage_states"]
    assert states["collect"] == ["Completed"] * 3 and states["train"] == ["Completed"]  # 2 shards + the merge
    assert states["evaluate"] == ["Completed"] * 2 and len(states["mimic"]) == 3
    assert summary["evaluation"]["episodes"] == 2 and 0.0 <= summary["success_rate"] <= 1.0
    for name, source in (("demos", "demos.hdf5"), ("mimic", "mimic.hdf5")):
        info = read_dataset_info(summary["artifacts"][name]["path"])
        assert info["num_demos"] == 2 and info["demo_ids"] == [0, 1]  # one episode per shard, renumbered
        assert info["provenance"][-1]["operation"] == "merge"
        for demo in info["demo_ids"]:
            ep = read_episode(info["path"], demo)
            assert ep["actions"].shape[0] == ep["attrs"]["num_samples"] and ep["attrs"]["source"].startswith(source)
    assert set(artifacts(dask_run["id"])) == set(ARTIFACT_KEYS.values())


def test_lost_worker_and_transient_error_are_retried(dask_run):
    tmp, states = dask_run["tmp"], dask_run["summary"]["stage_states"]
    assert (tmp / "collect.fault").exists() and (tmp / "mimic.fault").exists(), "the fault seam did not fire"
    # the Mimic shard whose worker was killed was re-run by Dask on a live worker; the flow records it
    assert sorted(states["mimic"]) == ["Completed", "Completed", "Completed (re-run after 1 lost worker)"], states
    runs = task_runs(dask_run["id"])
    retried = [(run, history) for run, history in runs["collect"] if RETRY_STATES & set(history)]
    assert len(runs["collect"]) == 2 and len(retried) == 1, runs["collect"]  # Prefect retried the I/O error
    assert retried[0][0].run_count == 2 and all(run.state_name == "Completed" for run, _ in runs["collect"])


def test_input_error_on_dask_is_not_retried_and_prints_one_line(harness, tmp_path):
    out = tmp_path / "out"
    for shard in (0, 1):
        stale_manifest(out / "shards" / f"collect_{shard}")
    proc = run_cli(["pipeline", *TINY_CLI, "--runner", "dask", "--workers", "2", "--out", str(out)], tmp_path)
    assert_input_error_reported_once(proc, out, shards=2)


def test_one_worker_per_gpu(monkeypatch):
    """With CUDA devices and no named device, the local cluster has one worker per GPU (at most ``workers``),
    each seeing only its GPU; a named device (cpu, cuda:N) or no GPU gives ``workers`` plain processes."""
    for workers, gpus in ((4, ["0", "1"]), (1, ["0", "1"]), (2, ["3", "5", "6"])):
        opts = cluster_options(workers, None, gpus=gpus)
        spec = opts["cluster_kwargs"]["workers"]
        assert [w["options"]["env"]["CUDA_VISIBLE_DEVICES"] for w in spec.values()] == gpus[:workers]
        assert all(w["options"]["nthreads"] == 1 for w in spec.values())
    assert cluster_options(2, "cuda", gpus=["0", "1"])["cluster_kwargs"]["workers"].keys() == {"gpu-0", "gpu-1"}
    for device, gpus in (("cpu", ["0", "1"]), ("cuda:1", ["0", "1"]), (None, [])):
        kwargs = cluster_options(3, device, gpus=gpus)["cluster_kwargs"]
        assert kwargs["n_workers"] == 3 and kwargs["threads_per_worker"] == 1, (device, gpus)
    # workers get NANNY_CLOSE_S to stop at shutdown (distributed's 5 s timed out on a loaded host)
    nanny = cluster_options(2, "cpu")["cluster_kwargs"]["worker_class"]
    assert nanny is next(iter(cluster_options(1, None, gpus=["0"])["cluster_kwargs"]["workers"].values()))["cls"]
    assert inspect.signature(nanny.close).parameters["timeout"].default == NANNY_CLOSE_S >= 30
    # the scheduler's HTTP endpoint takes a free local port, not distributed's 8787
    assert cluster_options(2, "cpu")["cluster_kwargs"]["scheduler_kwargs"]["dashboard_address"] == SCHEDULER_HTTP
    scheduler = cluster_options(1, None, gpus=["0"])["cluster_kwargs"]["scheduler"]["options"]
    assert scheduler["dashboard_address"] == SCHEDULER_HTTP == "127.0.0.1:0"
    for env, ids in (("2,3", ["2", "3"]), ("", []), ("-1", []), (" 1 ", ["1"])):
        monkeypatch.setenv("CUDA_VISIBLE_DEVICES", env)
        assert visible_gpus() == ids


def test_bench_collect_on_two_workers(tmp_path, capsys, recwarn):
    """``bench-collect --workers 2 --baseline``: worker 0 collects one share alone before and after two Dask worker
    processes collect at once, each into its own shard; the aggregate counts every demo over the span of both
    timed runs and ``scaling`` divides it by the mean of the lone runs' rates."""
    from newton_lab.cli import main

    path = tmp_path / "bc.zarr"
    with socket.socket() as taken:  # a dashboard already on distributed's port: no clash, no warning
        try:
            taken.bind(("127.0.0.1", 8787))
        except OSError:
            pass  # something else holds it already
        assert (
            main(
                [
                    "bench-collect",
                    "--workers",
                    "2",
                    "--num-envs",
                    "1",
                    "--episodes",
                    "2",
                    "--device",
                    "cpu",
                    "--dataset-path",
                    str(path),
                    "--baseline",
                ]
            )
            == 0
        )
    assert not [w for w in recwarn if "8787" in str(w.message)]
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["workers"] == 2 and out["successful_demos"] == 2 and out["device_names"] == ["cpu", "cpu"]
    parts = out["per_worker"]
    assert [p["successful_demos"] for p in parts] == [1, 1]
    assert out["wall_s"] >= max(p["wall_s"] for p in parts) * 0.99  # the span holds each worker's timed run
    assert out["demos_per_hour"] == pytest.approx(3600 * 2 / out["wall_s"])
    for p in parts:
        assert read_dataset_info(p["dataset_path"])["num_demos"] == 1 and p["physics_s"] > 0
        assert 0 < p["writer_files_s"] + p["writer_sync_s"] <= p["writer_s"] and p["presync_s"] >= 0
        assert p["inodes_per_demo"] > 50  # a zarr demo is a folder of array folders and files
    before, after = out["baseline"]
    for lone, name in ((before, "bc_alone.zarr"), (after, "bc_alone2.zarr")):
        assert lone["successful_demos"] == 1 and read_dataset_info(lone["dataset_path"])["num_demos"] == 1
        assert lone["dataset_path"].endswith(name) and lone["physics_s"] > 0
        assert lone["wall_s"] > 0 and "ready_at" not in lone  # the lone runs have no gate
    starts = [p["started_at"] for p in parts]
    assert before["started_at"] < min(starts) <= max(starts) < after["started_at"]  # the lone runs bracket theirs
    assert out["scaling"] == pytest.approx(out["demos_per_s"] / ((before["demos_per_s"] + after["demos_per_s"]) / 2))
    assert max(p["ready_at"] for p in parts) <= min(p["started_at"] for p in parts)  # timed runs start together
    assert out["start_skew_s"] == pytest.approx(max(starts) - min(starts))
    assert main(["bench-collect", "--workers", "2", "--device", "cpu", "--dataset-path", str(path)]) == 2
    assert "exists" in capsys.readouterr().err  # never overwrites a shard
    assert main(["bench-collect", "--baseline", "--device", "cpu", "--dataset-path", str(tmp_path / "y.zarr")]) == 2
    assert "--baseline compares --workers W" in capsys.readouterr().err
    assert (
        main(
            [
                "bench-collect",
                "--workers",
                "3",
                "--episodes",
                "2",
                "--device",
                "cpu",
                "--dataset-path",
                str(tmp_path / "x.zarr"),
            ]
        )
        == 2
    )
    assert "--workers 3 with --episodes 2" in capsys.readouterr().err
