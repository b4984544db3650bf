"""The long-horizon pipeline end to end on the CPU at its smallest size, as a user runs it: ``newton-lab pipeline``
on PickToShelf collects the coherent task with the front camera and no privileged observations, splits it by
phase, trains a visuomotor policy for pick and place (navigation stays the expert's), evaluates the composed task
and reports where its rows stopped; the same command again is answered from the cache. No success is expected
at this size."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from newton_lab.flows.stages import COLLECT_SECONDS

pytestmark = pytest.mark.slow

TASK = "GalbotG1-PickToShelf-v0"
COMMAND = [
    "pipeline",
    "--task",
    TASK,
    "--recipe",
    "cpu",
    "--demos",
    "2",
    "--num-envs",
    "2",
    "--eval-episodes",
    "2",
    "--train-steps",
    "5",
    "--eval-max-steps",
    "300",
    "--no-record",
    "--domain-randomize",
    "friction=mild,camera_shift=mild",
    "--distractors",
    "1",
    "--dataset-format",
    "zarr",
]
"""The smallest size: 5 training steps make a policy that may wander until the step limit, so the limit is 300
steps (an expert coherent episode is ~470). Collection is domain-randomised (the robust recipe's flag): each row
draws its own friction and camera offset, and a distractor object stands on the table. The datasets are zarr (the
single-task pipeline's tests run HDF5)."""


def run_pipeline(out: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PREFECT_HOME": str(out.parent / "prefect_home")}
    return subprocess.run(
        [sys.executable, "-m", "newton_lab.cli", *COMMAND, "--out", str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )


@pytest.fixture(scope="module")
def first_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("long_horizon") / "run"
    done = run_pipeline(out)
    assert done.returncode == 0, done.stderr[-3000:]
    return out, done.stdout


def test_every_stage_ran_and_the_composed_task_was_evaluated(first_run):
    out, stdout = first_run
    assert "stages: collect Completed, split Completed, train Completed/Completed, evaluate Completed" in stdout
    summary = json.loads((out / "metrics.json").read_text())
    assert summary["learned_phases"] == ["pick", "place"]
    ev = summary["evaluation"]
    assert ev["episodes"] == 2 and list(ev["phases"]) == ["pick", "nav", "place"]
    assert ev["phases"]["pick"]["reached"] == 2  # every row starts in pick; later phases only if it passed
    assert "recording" not in ev and not (out / "evaluation.rrd").exists()  # --no-record: rerun-sdk not needed
    assert "phase pick" in stdout and "composed" in stdout and "passed" in stdout
    record = json.loads(Path(json.loads(stdout.strip().splitlines()[-1])["record"]).read_text())
    assert record["command"].startswith(f"newton-lab pipeline --task {TASK} --recipe cpu")
    assert record["results"]["learned_phases"] == ["pick", "place"] and record["results"]["recipe"] == "cpu"
    assert set(record["results"]["phases"]) == {"pick", "nav", "place"}
    assert set(record["results"]["subtask_signals"]) == set(ev["subtask_signals"]) >= {"grasped_bar"}
    assert "signals" in stdout and "grasped_bar" in stdout
    assert set(record["results"]["timings_s"]) == {"collect", "split", "train", "evaluate", "flow"}
    seconds = record["results"]["collect_seconds"]  # where the collect stage went, each part inside the one above it
    assert set(seconds) == set(COLLECT_SECONDS)
    assert 0 < seconds["loop"] <= seconds["collect"] < seconds["call"] <= record["results"]["timings_s"]["collect"]
    assert record["results"]["domain_randomize"] == {"friction": 0.7, "camera_shift": 2.0}
    from newton_lab.datasets import DatasetRef

    (entry,) = [
        p for p in DatasetRef.open(summary["artifacts"]["demos"]["path"]).provenance if p.operation == "collect"
    ]
    assert {k: len(v) for k, v in entry.config["domain_randomization"].items()} == {"friction": 2, "camera_shift": 2}
    assert record["results"]["distractors"] == 1  # the demos stood among one; the evaluation on the task's own scene
    from newton_lab.datasets import read_dataset_info, read_episode

    assert read_dataset_info(summary["artifacts"]["demos"]["path"])["env_args"]["env_kwargs"]["distractors"] == 1
    # the phase datasets carry the component task and only the phase's columns; each policy trained on its own
    phases = summary["artifacts"]["phases"]
    assert (
        summary["artifacts"]["demos"]["path"].endswith("demos.zarr") and record["results"]["dataset_format"] == "zarr"
    )
    for name, component in (("pick", "Pick"), ("place", "Place"), ("nav", "Nav")):
        assert phases[name]["path"].endswith(f"{name}.zarr")
        assert read_dataset_info(phases[name]["path"])["env_args"]["env_name"] == f"GalbotG1-PickToShelf-{component}-v0"

    for name, index in (("pick", 0), ("place", 2)):  # each segment holds its demo's very frames of the phase
        seg = read_episode(phases[name]["path"], 0)
        demo = read_episode(summary["artifacts"]["demos"]["path"], int(seg["attrs"]["source"].split(":")[1]))
        rows = np.nonzero(np.asarray(demo["datagen"]["phase"]).reshape(-1) == index)[0]
        np.testing.assert_array_equal(seg["obs"]["front_head_rgb"], demo["obs"]["front_head_rgb"][rows])
    for name in ("pick", "place"):
        ckpt = torch.load(summary["artifacts"]["checkpoints"][name]["path"], weights_only=True)
        assert ckpt["info"]["task_id"] == f"GalbotG1-PickToShelf-{name.title()}-v0"
        assert ckpt["info"]["image_keys"] == ["front_head_rgb"]
        assert list(ckpt["info"]["obs_keys"]) == ["robot_joint_pos", "gripper_pos"]  # proprioception, no pose


def test_the_same_command_is_answered_from_the_cache(first_run):
    out, _ = first_run
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*.zarr/**/*") if p.is_file()}
    again = run_pipeline(out)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "stages: collect Cached, split Cached, train Cached/Cached, evaluate Cached" in again.stdout
    assert before and {p: p.stat().st_mtime_ns for p in out.rglob("*.zarr/**/*") if p.is_file()} == before
