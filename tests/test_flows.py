"""The Prefect pipeline end to end with tiny sizes: caching on re-run, retry of a failing stage, Dask shards."""

from __future__ import annotations

import json

import pytest

import newton_lab.policies as policies
from newton_lab.datasets import read_dataset_info, read_episode
from newton_lab.flows import settings
from newton_lab.flows.stages import _finish, _guard

pytestmark = pytest.mark.slow

TINY_TRAIN = {"down_dims": [16, 32, 64], "batch_size": 32, "max_steps": 3, "epochs": 1, "warmup_steps": 1,
              "progress": False}
TINY = dict(task_id="GalbotG1-PickCube-v0", demos=2, mimic_episodes=2, train_cfg=TINY_TRAIN, eval_episodes=2,
            num_envs=2, device="cpu", eval_max_steps=10)


@pytest.fixture(scope="module")
def harness(tmp_path_factory):
    settings.configure(tmp_path_factory.mktemp("prefect_home"))
    from prefect.testing.utilities import prefect_test_harness  # deferred: Prefect reads settings.configure's home

    with prefect_test_harness(server_startup_timeout=120):
        yield


STAGES = ("collect", "mimic", "train", "evaluate")


def test_pipeline_runs_then_is_cached(harness, tmp_path):
    from newton_lab.flows import pipeline  # deferred: imports Prefect (after the harness configured it)

    out = tmp_path / "out"
    first = pipeline(out=str(out), **TINY)
    assert set(first["artifacts"]) == {"demos", "mimic", "checkpoint"}
    assert first["evaluation"]["episodes"] == 2 and 0.0 <= first["success_rate"] <= 1.0
    assert json.loads((out / "metrics.json").read_text())["task"] == "GalbotG1-PickCube-v0"
    assert first["stage_states"] == {s: ["Completed"] for s in STAGES}
    second = pipeline(out=str(out), **TINY)
    assert second["artifacts"] == first["artifacts"]
    assert second["stage_states"] == {s: ["Cached"] for s in STAGES}  # the re-run computed nothing


def test_failed_stage_is_retried(harness, tmp_path, monkeypatch):
    from newton_lab.flows import pipeline  # deferred: imports Prefect (after the harness configured it)

    real = policies.Policy.from_backend
    calls = {"n": 0}

    def flaky(name):
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("injected training failure")
        return real(name)

    monkeypatch.setattr(policies.Policy, "from_backend", staticmethod(flaky))
    summary = pipeline(out=str(tmp_path / "retry"), **TINY)
    # train failed once, its retry completed (the evaluation loads the checkpoint through from_backend too)
    assert calls["n"] == 3 and summary["stage_states"]["train"] == ["Completed"]
    assert summary["evaluation"]["episodes"] == 2


def test_input_error_in_a_stage_is_not_retried(harness, tmp_path, monkeypatch):
    from newton_lab.flows import pipeline  # deferred: imports Prefect (after the harness configured it)

    calls = {"n": 0}

    def bad_input(name):
        calls["n"] += 1
        raise ValueError("injected input error")

    monkeypatch.setattr(policies.Policy, "from_backend", staticmethod(bad_input))
    with pytest.raises(ValueError, match="injected input error"):
        pipeline(out=str(tmp_path / "no_retry"), **TINY)
    assert calls["n"] == 1, "a deterministic input error must not be retried"


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


def test_dask_shards_match_single_worker(harness, tmp_path):
    from prefect_dask import DaskTaskRunner  # deferred: Dask and Prefect are slow to import

    from newton_lab.flows import collect  # deferred: imports Prefect (after the harness configured it)

    single, _ = collect("GalbotG1-Reach-v0", episodes=4, num_envs=2, device="cpu", out=str(tmp_path / "one"))
    runner = DaskTaskRunner(cluster_kwargs={"n_workers": 2, "processes": True, "threads_per_worker": 1,
                                            "dashboard_address": None})
    merged, states = collect.with_options(task_runner=runner)("GalbotG1-Reach-v0", episodes=4, num_envs=2,
                                                              device="cpu", out=str(tmp_path / "two"), shards=2)
    assert states == ["Completed", "Completed", "Completed"]  # two shards and the merge
    a, b = read_dataset_info(single["path"]), read_dataset_info(merged["path"])
    assert a["num_demos"] == b["num_demos"] == 4 and b["demo_ids"] == [0, 1, 2, 3]
    assert [p["operation"] for p in b["provenance"]] == ["merge"]
    for demo in b["demo_ids"]:
        ep = read_episode(merged["path"], demo)
        assert ep["actions"].shape[0] == ep["attrs"]["num_samples"] and ep["attrs"]["source"].startswith("demos.hdf5")
