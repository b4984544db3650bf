"""The demo recipes of ``newton-lab pipeline`` / ``make demo`` and the lines the pipeline ends with (no physics:
configuration and reporting only; the recipe's figures come from the pipeline runs on docs/benchmarks.md)."""

from __future__ import annotations

import pytest
from newton_lab.flows.report import summary_lines
from newton_lab.flows.settings import DEMO_RECIPES, demo_recipe

from newton_lab.commands import PipelineArgs
from newton_lab.policies import DiffusionPolicyConfig


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    """Overrides the conftest fixture: these tests never import warp."""
    yield


def test_recipes_resolve_their_devices():
    cpu = demo_recipe("auto", "cpu")
    assert cpu["name"] == "cpu" and cpu["device"] == "cpu" and cpu["train_device"] == "cpu"
    assert cpu["eval_episodes"] >= 20 and cpu["mimic_episodes"] > cpu["demos"]
    gpu = demo_recipe("auto", "cuda:1")
    assert gpu["name"] == "gpu" and gpu["device"] == gpu["train_device"] == "cuda:1"
    bare = demo_recipe("gpu")  # no device: Warp's default for the envs, torch's CUDA device for training
    assert bare["device"] is None and bare["train_device"] == "cuda"
    assert demo_recipe("cpu", "cuda:0")["train"] == DEMO_RECIPES["cpu"]["train"]  # small recipe on a GPU
    with pytest.raises(ValueError, match="unknown demo recipe 'huge'; valid recipes: auto, cpu, gpu"):
        demo_recipe("huge")


@pytest.mark.parametrize("name", sorted(DEMO_RECIPES))
def test_recipe_training_configs_are_valid_and_predict_x0(name):
    train = PipelineArgs(recipe=name).train_cfg(demo_recipe(name, "cpu" if name == "cpu" else "cuda:0"))
    cfg = DiffusionPolicyConfig.from_dict(train)
    assert cfg.prediction_type == "sample" and ((cfg.max_steps or 0) >= 2000 or (cfg.time_budget_s or 0) >= 120)
    for count in ("demos", "mimic_episodes", "eval_episodes", "num_envs"):  # full size: never fewer
        assert DEMO_RECIPES[name][count] >= DEMO_RECIPES["cpu"][count]


def test_the_gpu_demo_learns_from_pixels_and_proprioception_only():
    """The full-size demo's policy sees a camera it records and proprioception; no object pose reaches it."""
    from newton_lab.task_api.cfg import parse_cameras

    recipe = demo_recipe("gpu", "cuda:0")
    kwargs = PipelineArgs().pipeline_kwargs(recipe)
    cfg = DiffusionPolicyConfig.from_dict(kwargs["train_cfg"])
    recorded = {f"{cam}_{data}" for cam, spec in parse_cameras(kwargs["cameras"]).items() for data in spec["data"]}
    assert cfg.image_keys and set(cfg.image_keys) <= recorded and cfg.bf16
    assert kwargs["task_options"] == {"obs_mode": "sensors"} and kwargs["recipe"] == "gpu"
    assert not any("pose" in k for k in cfg.obs_keys or ()), cfg.obs_keys
    cpu = PipelineArgs().pipeline_kwargs(demo_recipe("cpu"))  # the CPU recipe stays a state policy
    assert cpu["cameras"] == "none" and cpu["task_options"] == {}


def test_flags_override_the_recipe():
    recipe = demo_recipe("cpu")
    kwargs = PipelineArgs().pipeline_kwargs(recipe)
    assert {k: kwargs[k] for k in ("demos", "mimic_episodes", "eval_episodes", "num_envs", "device")} == {
        k: recipe[k] for k in ("demos", "mimic_episodes", "eval_episodes", "num_envs", "device")
    }
    assert kwargs["train_cfg"] == {**recipe["train"], "device": "cpu"}
    given = PipelineArgs(demos=2, mimic_episodes=3, eval_episodes=5, train_steps=7).pipeline_kwargs(recipe)
    assert (given["demos"], given["mimic_episodes"], given["eval_episodes"]) == (2, 3, 5)
    assert given["train_cfg"]["max_steps"] == 7 and given["num_envs"] == recipe["num_envs"]


def test_summary_names_every_figure_and_where_to_look(tmp_path, monkeypatch):
    monkeypatch.delenv("PREFECT_API_URL", raising=False)
    monkeypatch.setenv("PREFECT_HOME", str(tmp_path / ".prefect"))
    ckpt = tmp_path / "policy" / "checkpoint.pt"
    summary = {
        "task": "GalbotG1-PickCube-v0",
        "artifacts": {
            "demos": {"path": "d.hdf5", "metrics": {"episodes": 4, "success_rate": 1.0}},
            "mimic": {
                "path": "m.hdf5",
                "metrics": {"episodes": 100, "attempts": 104, "generation_success_rate": 100 / 104},
            },
            "checkpoint": {"path": str(ckpt), "metrics": {"final_loss": 0.00361, "steps": 2000, "wall_time_s": 212.4}},
        },
        "evaluation": {
            "episodes": 20,
            "successes": 19,
            "success_rate": 0.95,
            "recording": str(tmp_path / "evaluation.rrd"),
        },
    }
    text = "\n".join(summary_lines(summary, tmp_path, "cpu"))
    for part in (
        "(cpu recipe)",
        "4 collected, 100% success",
        "100 demos generated from 104 attempts (96% success)",
        "2000 steps, 212 s, final loss 0.0036",
        "95.0% success over 20 held-out randomised evaluation",
        "(19 succeeded)",
        str(tmp_path / "metrics.json"),
        str(ckpt),
        "evaluation.rrd (open it with: rerun",
        f"PREFECT_HOME={tmp_path / '.prefect'} PREFECT_SERVER_UI_ENABLED=true",
        "server start",
        "http://127.0.0.1:4200",
    ):
        assert part in text, (part, text)
    monkeypatch.setenv("PREFECT_API_URL", "http://prefect.lab:4200/api")
    del summary["evaluation"]["recording"]
    text = "\n".join(summary_lines(summary, tmp_path))
    assert "http://prefect.lab:4200 (your server)" in text and ".rrd" not in text


@pytest.mark.parametrize("name", ["cpu", "gpu"])
def test_long_horizon_recipe_records_every_camera_its_policies_see(name):
    from newton_lab.task_api.cfg import parse_cameras

    recipe = demo_recipe(name, "cpu" if name == "cpu" else "cuda:0", long_horizon=True)
    args = PipelineArgs(task="GalbotG1-PickToShelf-v0", recipe=name)
    kwargs = args.pipeline_kwargs(recipe)
    cfg = DiffusionPolicyConfig.from_dict(kwargs["train_cfg"])
    recorded = {f"{cam}_{data}" for cam, spec in parse_cameras(kwargs["cameras"]).items() for data in spec["data"]}
    assert cfg.image_keys and set(cfg.image_keys) <= recorded, (cfg.image_keys, kwargs["cameras"])
    assert "object_pose" not in (cfg.obs_keys or ()) and kwargs["task_options"] == {}


def test_train_image_keys_flag_overrides_the_preset():
    from newton_lab.commands.workflow import TrainArgs
    from newton_lab.policies.config import PRESETS

    args = TrainArgs(dataset_path=["d.hdf5"], preset="vision", image_keys="front_head_rgb, left_wrist_rgb")
    assert args.train_cfg(PRESETS)["image_keys"] == ("front_head_rgb", "left_wrist_rgb")
    assert "image_keys" not in TrainArgs(dataset_path=["d.hdf5"], preset="default").train_cfg(PRESETS)


def test_no_record_reaches_the_flow():
    assert PipelineArgs().pipeline_kwargs(demo_recipe("cpu"))["record"] is True
    assert PipelineArgs(record=False).pipeline_kwargs(demo_recipe("cpu"))["record"] is False


def test_a_task_recipe_overrides_counts_and_training_but_keeps_the_rest():
    base = demo_recipe("gpu", "cuda:0", long_horizon=True)
    stack = demo_recipe("gpu", "cuda:0", long_horizon=True, task="GalbotG1-StackCube-Phased-v0")
    assert stack["demos"] == 800 and stack["train"]["time_budget_s"] == 600
    assert {k: v for k, v in stack["train"].items() if k != "time_budget_s"} == {
        k: v for k, v in base["train"].items() if k != "time_budget_s"
    }
    assert stack["cameras"] == base["cameras"] and stack["eval_episodes"] == base["eval_episodes"]
    assert demo_recipe("cpu", "cpu", long_horizon=True, task="GalbotG1-StackCube-Phased-v0")["demos"] == 4
