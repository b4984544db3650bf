"""DatasetRef: provenance stored in the dataset, drop() of the last collect call."""

from __future__ import annotations

from newton_lab.agents import PlannerAgent
from newton_lab.datasets import DatasetRef, read_dataset_info


def test_collect_returns_ref_with_provenance_and_drop(reach_env, tmp_path):
    path = tmp_path / "reach.hdf5"
    first = reach_env.collect(
        agent=PlannerAgent.from_task(reach_env.task_id), episodes=2, path=path, max_steps=200, progress=False
    )
    assert isinstance(first, DatasetRef) and first.task_id == "GalbotG1-Reach-v0"
    assert first["episodes"] == 2 and first.metadata["saved_demo_ids"] == [0, 1]
    second = reach_env.collect(
        agent=PlannerAgent.from_task(reach_env.task_id), episodes=1, path=path, max_steps=200, progress=False
    )
    assert second["saved_demo_ids"] == [2]
    dropped = second.drop()  # e.g. a teleop reviewer said "drop"
    info = read_dataset_info(path)
    assert info["demo_ids"] == [0, 1] and info["num_demos"] == 2
    assert info["total"] == sum(first["episode_lengths"])
    assert dropped.metadata["dropped_demo_ids"] == [2]
    ops = [p.operation for p in DatasetRef.open(path).provenance]
    assert ops == ["collect", "collect", "drop"]
    assert DatasetRef.open(path).provenance[0].config["num_envs"] == reach_env.num_envs
