"""The console script and the benchmark."""

from __future__ import annotations

import argparse
import json

import pytest

from newton_lab.cli import REQUIRED, build_parser, main, parse_args
from newton_lab.commands import CollectArgs, EvaluateArgs, TrainArgs
from newton_lab.task_api.catalog import declared_options, declared_task_ids
from newton_lab.task_api.registry import list_tasks, lookup


def test_tasks_lists_every_id(capsys):
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    for task in ("GalbotG1-PickCube-v0", "GalbotG1-StackCube-v0", "GalbotG1-Reach-v0"):
        assert task in out


def test_collect_prints_one_json_line(tmp_path, capsys):
    path = tmp_path / "data" / "reach.zarr"  # data/ does not exist yet: the command creates it
    rc = main(
        [
            "collect",
            "--task",
            "GalbotG1-Reach-v0",
            "--episodes",
            "2",
            "--num-envs",
            "2",
            "--randomize",
            "--device",
            "cpu",
            "--no-progress",
            "--dataset-path",
            str(path),
        ]
    )
    assert rc == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    summary = json.loads(line)
    assert {"task", "episodes", "successes", "success_rate", "path"} <= set(summary)
    assert summary["episodes"] == 2 and summary["success_rate"] == 1.0 and summary["path"] == str(path)


def test_cli_reports_bad_input_in_one_line(capsys):
    assert main(["collect", "--task", "GalbotG1-Nope-v0", "--device", "cpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown task id" in err and "GalbotG1-PickCube-v0" in err


def test_task_ids_read_from_source_are_the_registry():
    """The CLI checks --task against ids read from the task packages' source (no import); they must be the
    registered ones."""
    from newton_lab import tasks  # noqa: F401  registers every id

    assert declared_task_ids() == tuple(list_tasks()) and len(list_tasks()) >= 10


def test_task_options_read_from_source_are_the_registry():
    """Task options become flags from the task packages' source (no import): names and literal choices must be
    those the registry checks."""
    from newton_lab import tasks  # noqa: F401  registers every id

    declared = declared_options()
    assert set(declared) == set(list_tasks())
    for task_id in list_tasks():
        spec = lookup(task_id)
        assert [o.name for o in declared[task_id]] == spec.option_names, task_id
        for source, real in zip(declared[task_id], spec.options):
            assert source.choices in (None, real.choices), task_id


def test_an_option_the_task_does_not_take_is_refused_at_once(capsys):
    rc = main(["collect", "--task", "GalbotG1-PickCube-v0", "--sorting-object", "red_cube", "--device", "cpu"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0
    assert "GalbotG1-PickCube-v0 takes no option --sorting-object" in err and "its options: --obs-mode" in err


def test_task_option_typo_names_the_closest_value(capsys):
    rc = main(["collect", "--task", "GalbotG1-SortToShelf-Pick-v0", "--sorting-object", "red_cub", "--device", "cpu"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and "unknown sorting_object 'red_cub' (did you mean red_cube?)" in err


def test_version_and_defaults_in_help(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip().startswith("newton-lab 0.")
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    text = " ".join(sub.choices["collect"].format_help().split())
    assert "(default: GalbotG1-PickCube-v0)" in text and "(default: data/pick_cube_demos.hdf5)" in text
    assert "(default: 1000)" in text and "--verbose" in text
    assert "(default: None)" not in text and "(default: False)" not in text


@pytest.mark.slow
def test_bench_prints_side_by_side_figures(capsys):
    assert (
        main(
            [
                "bench",
                "--task",
                "GalbotG1-PickCube-v0",
                "--num-envs",
                "1",
                "--steps",
                "10",
                "--device",
                "cpu",
                "--camera",
                "front_head",
                "--resolution",
                "32",
                "24",
                "--camera-data",
                "rgb",
                "depth",
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["env_steps_per_s"] > 0 and out["bare_world_steps_per_s"] > 0 and out["ratio_env_step_to_bare"] > 0
    assert out["resolution"] == [32, 24] and out["camera_data"] == ["rgb", "depth"]
    assert out["env_steps_per_s_with_camera"] > 0 and out["ceiling_env_steps_per_s"] > 0
    assert out["ratio_camera_env_to_ceiling"] > 0


@pytest.mark.slow
def test_bench_times_several_cameras_against_their_bare_renders(capsys):
    argv = ["bench", "--task", "GalbotG1-PickCube-v0", "--num-envs", "1", "--steps", "5", "--device", "cpu"]
    assert main([*argv, "--cameras", "front_head=32x24:rgb,left_wrist=24x16:rgb+depth"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["cameras"] == {"front_head": [32, 24, ["rgb"]], "left_wrist": [24, 16, ["rgb", "depth"]]}
    assert out["camera"] == "front_head+left_wrist" and out["ceiling_env_steps_per_s"] > 0
    assert out["env_steps_per_s_with_camera"] > 0 and out["ratio_camera_env_to_ceiling"] > 0
    assert main([*argv, "--cameras", "front_head=32x24:rgb", "--camera", "front_head"]) == 2
    assert "--camera and --cameras both given" in capsys.readouterr().err


@pytest.mark.slow
def test_bench_collect_splits_the_time(capsys, tmp_path):
    path = tmp_path / "b.hdf5"
    assert (
        main(
            [
                "bench-collect",
                "--num-envs",
                "2",
                "--episodes",
                "2",
                "--prefill",
                "20",
                "--device",
                "cpu",
                "--dataset-path",
                str(path),
                "--run-record",
                str(tmp_path / "record.json"),
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["successful_demos"] == 2 and out["demos_per_hour"] == pytest.approx(3600 * out["demos_per_s"])
    assert min(out["physics_s"], out["agent_s"], out["writer_s"], out["first_use_s"]) > 0
    assert out["physics_s"] + out["agent_s"] <= out["wall_s"] and out["bytes_per_demo"] > 1000
    assert out["inodes_per_demo"] == 0.5  # one HDF5 file for the two demos
    assert out["prefill_episodes"] == 20 and out["prefilled_demos_per_s"] > 0 and out["presync_s"] >= 0
    assert "writer_sync_s" not in out  # the split is zarr's
    assert out["cameras"] == {} and json.loads((tmp_path / "record.json").read_text())["kind"] == "bench-collect"
    assert main(["bench-collect", "--dataset-path", str(path), "--device", "cpu"]) == 2  # never overwrites
    assert "exists" in capsys.readouterr().err


@pytest.mark.slow
def test_bench_collect_with_cameras_times_their_render_apart(capsys, tmp_path):
    assert (
        main(
            [
                "bench-collect",
                "--num-envs",
                "2",
                "--episodes",
                "2",
                "--prefill",
                "0",
                "--device",
                "cpu",
                "--cameras",
                "front_head=32x24:rgb",
                "--obs-mode",
                "sensors",
                "--dataset-path",
                str(tmp_path / "c.zarr"),
                "--run-record",
                str(tmp_path / "record.json"),
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    out = json.loads(captured.out.strip().splitlines()[-1])
    assert out["cameras"] == {"front_head": [32, 24, ["rgb"]]} and out["successful_demos"] == 2
    assert out["record_s"] > 0 and "render and frames" in captured.err
    from newton_lab.datasets import read_dataset_info

    info = read_dataset_info(tmp_path / "c.zarr")
    assert info["env_args"]["env_kwargs"]["task_options"]["obs_mode"] == "sensors"


@pytest.mark.slow
def test_bench_collect_traces_a_window_of_steps_with_each_stage_labelled(capsys, tmp_path):
    import gzip

    trace = tmp_path / "collect.json.gz"
    assert (
        main(
            [
                "bench-collect",
                "--num-envs",
                "2",
                "--episodes",
                "2",
                "--prefill",
                "0",
                "--device",
                "cpu",
                "--dataset-path",
                str(tmp_path / "b.zarr"),
                "--trace",
                str(trace),
                "--trace-after",
                "60",
                "--run-record",
                str(tmp_path / "record.json"),
            ]
        )
        == 0
    )
    events = json.loads(gzip.decompress(trace.read_bytes()))["traceEvents"]
    names = {e.get("name") for e in events}
    assert {"physics", "agent"} <= names  # the stage ranges
    assert sum(e.get("name") == "physics" for e in events) == 20  # TRACE_STEPS env steps, no more
    assert any(e.get("cat") == "python_function" for e in events)  # the Python tracer: which call waits
    table = (tmp_path / "collect.json.gz.txt").read_text()
    assert "physics" in table and "self_cpu_time_total" in table


REQ = "<required>"
LEGACY_FLAGS = {  # every flag (and default) of the hand-written parser the dataclass-generated one replaced
    "collect": {
        "--task": "GalbotG1-PickCube-v0",
        "--episodes": 1,
        "--num-envs": 1,
        "--max-steps": 1000,
        "--device": None,
        "--seed": 0,
        "--randomize": False,
        "--no-progress": False,
        "--rerun": False,
        "--rerun-save": None,
        "--rerun-worlds": 4,
        "--sorting-object": None,
        "--init-scenario": None,
        "--dataset-path": "data/pick_cube_demos.hdf5",
        "--save-end-scenario": None,
    },
    "evaluate": {
        "--task": "GalbotG1-PickCube-v0",
        "--episodes": 1,
        "--num-envs": 1,
        "--max-steps": 1000,
        "--device": None,
        "--seed": 0,
        "--randomize": False,
        "--no-progress": False,
        "--rerun": False,
        "--rerun-save": None,
        "--rerun-worlds": 4,
        "--sorting-object": None,
        "--init-scenario": None,
        "--checkpoint": None,
    },
    "mimic": {
        "--dataset-path": REQ,
        "--output-path": None,
        "--episodes": 36,
        "--num-envs": 8,
        "--max-attempts": None,
        "--seed": 1,
        "--device": None,
        "--no-progress": False,
    },
    "train": {
        "--dataset-path": REQ,
        "--output-dir": "outputs/policy",
        "--preset": "default",
        "--epochs": None,
        "--max-steps": None,
        "--batch-size": None,
        "--lr": None,
        "--obs-keys": None,
        "--prediction-type": None,
        "--init-checkpoint": None,
        "--time-budget-s": None,
        "--device": "cpu",
        "--seed": 0,
    },
    "split": {"--dataset-path": REQ, "--out": None, "--val-ratio": 0.1, "--filter-key": None, "--seed": 0},
    "export": {"--dataset-path": REQ, "--root": REQ, "--include-failed": False},
    "pipeline": {
        "--task": "GalbotG1-PickCube-v0",
        "--recipe": "auto",
        "--demos": None,
        "--mimic-episodes": None,
        "--train-steps": None,
        "--eval-episodes": None,
        "--num-envs": None,
        "--device": None,
        "--seed": 0,
        "--out": "outputs/pipeline",
        "--runner": "local",
        "--workers": 1,
        "--address": None,
        "--retries": 1,
    },
    "view": {"dataset": REQ, "--episode": 0, "--save": None, "--spawn": False},
    "bench": {"--task": "GalbotG1-PickCube-v0", "--num-envs": 4, "--steps": 200, "--device": None},
    "bench-train": {
        "--dataset-path": REQ,
        "--batch-size": 1024,
        "--steps": 200,
        "--preset": "default",
        "--device": "cpu",
    },
}


def test_generated_parser_keeps_every_flag_and_default():
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert set(LEGACY_FLAGS) | {"tasks", "render", "bench-collect"} <= set(sub.choices)  # later commands are new
    for command, flags in LEGACY_FLAGS.items():
        actions = {s: a for a in sub.choices[command]._actions for s in (a.option_strings or [a.dest])}
        for flag, default in flags.items():
            a = actions[flag]
            assert (REQ if a.required else a.default) == default, (command, flag)
        assert all(a.help for a in actions.values()), command  # every flag documented (its field docstring)


def test_parse_args_builds_the_dataclass(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    import torch

    from newton_lab.policies.diffusion import CHECKPOINT_FORMAT, CHECKPOINT_VERSION

    torch.save(
        {
            "format": CHECKPOINT_FORMAT,
            "version": CHECKPOINT_VERSION,
            "config": {},  # the header the CLI reads
            "info": {"task_id": "GalbotG1-Reach-v0"},
        },
        tmp_path / "c.pt",
    )
    a = parse_args(
        CollectArgs,
        ["--task", "GalbotG1-SortToShelf-Pick-v0", "--num-envs", "2", "--sorting-object", "red_cube", "--randomize"],
    )
    assert isinstance(a, CollectArgs) and a.num_envs == 2 and a.randomize and a.episodes == 1
    assert (tmp_path / "data").is_dir()  # the example's output folder is made, as the CLI makes it
    assert a.env_kwargs()["task_options"] == {"sorting_object": "red_cube"}
    from test_policy import write_dataset  # inputs must open: two real (tiny) datasets

    write_dataset(tmp_path / "a.hdf5"), write_dataset(tmp_path / "b.hdf5")
    t = parse_args(
        TrainArgs,
        ["--dataset-path", "a.hdf5", "b.hdf5", "--learning-rate", "0.001", "--obs-keys", "cube_pose, robot_joint_pos"],
    )
    cfg = t.train_cfg({"default": {"epochs": 7}})
    assert t.datasets() == ["a.hdf5", "b.hdf5"] and cfg["lr"] == 0.001 and cfg["epochs"] == 7
    assert cfg["obs_keys"] == ("cube_pose", "robot_joint_pos") and "batch_size" not in cfg
    # an example's own defaults: a required checkpoint, randomised resets on (--no-randomize turns them off)
    example = {"checkpoint": REQUIRED, "randomize": True, "task": "GalbotG1-Reach-v0"}
    e = parse_args(EvaluateArgs, ["--checkpoint", "c.pt", "--no-randomize"], defaults=example, exclude=("task",))
    assert e.checkpoint == "c.pt" and e.randomize is False and e.task == "GalbotG1-Reach-v0"
    with pytest.raises(SystemExit) as exit_:
        parse_args(EvaluateArgs, [], defaults=example)
    assert exit_.value.code == 2
    with pytest.raises(SystemExit) as exit_:  # checked as the CLI checks it
        parse_args(CollectArgs, ["--task", "GalbotG1-Reach-v1"])
    assert exit_.value.code == 2 and "(did you mean GalbotG1-Reach-v0?)" in capsys.readouterr().err


def test_train_reports_an_unknown_preset_in_one_line(tmp_path, capsys):
    from test_policy import write_dataset

    data = write_dataset(tmp_path / "d.hdf5")
    assert main(["train", "--dataset-path", str(data), "--preset", "huge"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unknown training preset 'huge'" in err and "cpu" in err
