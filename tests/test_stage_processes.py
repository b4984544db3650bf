"""On a CUDA device the pipeline's env stages (collect, Mimic, evaluate) each run in a spawned process of their own,
so that the device memory their envs reserve goes back when they end instead of staying with the flow's process
through the trainings that follow. The same path, forced on the CPU: the stage runs in another process, and its
demos and artifact are what the flow's process would have made."""

from __future__ import annotations

import os

from newton_lab.flows import stages

from newton_lab.commands import CollectArgs
from newton_lab.datasets import read_dataset_info


def test_an_env_stage_runs_in_a_process_of_its_own_where_cuda_would(tmp_path, monkeypatch):
    assert stages._on_device("cpu", os.getpid) == os.getpid()  # the CPU path stays in the flow's process
    monkeypatch.setattr(stages, "IN_OWN_PROCESS_ON_CPU", True)
    assert stages._on_device("cpu", os.getpid) != os.getpid()
    args = CollectArgs(
        task="GalbotG1-Reach-v0",
        episodes=2,
        num_envs=2,
        device="cpu",
        seed=3,
        randomize=True,
        no_progress=True,
        dataset_path=str(tmp_path / "demos.hdf5"),
    )
    art = stages.collect_stage(args=args)
    info = read_dataset_info(tmp_path / "demos.hdf5")
    assert art["metrics"]["episodes"] == 2 and len(info["demo_ids"]) == 2
    assert art["metrics"]["samples"] == info["total"] > 0
    seconds = art["metrics"]["seconds"]  # timed inside the stage's process, handed back with its result
    assert set(seconds) == set(stages.COLLECT_SECONDS) and 0 < seconds["loop"] <= seconds["collect"] < seconds["call"]
    assert (tmp_path / "demos.manifest.json").is_file()
    assert stages.collect_stage(args=args)["sha256"] == art["sha256"]  # the finished stage is answered from disk
