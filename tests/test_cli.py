"""The console script and the benchmark."""

from __future__ import annotations

import json

import pytest

from newton_lab.cli import main


def test_tasks_lists_every_id(capsys):
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    for task in ("GalbotG1-PickCube-v0", "GalbotG1-StackCube-v0", "GalbotG1-Reach-v0"):
        assert task in out


def test_collect_prints_one_json_line(tmp_path, capsys):
    path = tmp_path / "reach.zarr"
    rc = main(["collect", "--task", "GalbotG1-Reach-v0", "--episodes", "2", "--num-envs", "2", "--randomize",
               "--device", "cpu", "--no-progress", "--dataset-path", str(path)])
    assert rc == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    summary = json.loads(line)
    assert {"task", "episodes", "successes", "success_rate", "path"} <= set(summary)
    assert summary["episodes"] == 2 and summary["success_rate"] == 1.0 and summary["path"] == str(path)


def test_cli_reports_bad_input_in_one_line(capsys):
    assert main(["collect", "--task", "GalbotG1-Nope-v0", "--device", "cpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown task id" in err and "GalbotG1-PickCube-v0" in err


@pytest.mark.slow
def test_bench_prints_side_by_side_figures(capsys):
    assert main(["bench", "--task", "GalbotG1-PickCube-v0", "--num-envs", "1", "--steps", "10", "--device", "cpu"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["env_steps_per_s"] > 0 and out["bare_world_steps_per_s"] > 0 and out["ratio_env_step_to_bare"] > 0
