"""The ``newton-lab`` subcommands: each one's argument dataclass (``newton_lab.commands``), what it does (the
command modules beside this one) and its one-line help, in ``--help`` order."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .. import commands as c
from . import bench, datasets, env, perception, pipeline, rl, suite, workflow


@dataclass(frozen=True)
class Command:
    """A subcommand: its argument dataclass, what it does, its one-line help."""

    args: type
    run: Callable[[object], int]
    help: str


COMMANDS: dict[str, Command] = {
    "tasks": Command(c.TasksArgs, env.list_task_ids, "list registered task ids"),
    "collect": Command(
        c.CollectArgs, workflow.collect, "collect expert episodes into HDF5 (.hdf5/.h5) or zarr (.zarr)"
    ),
    "evaluate": Command(
        c.EvaluateArgs, workflow.evaluate, "run a policy checkpoint (or the expert planner) and report the success rate"
    ),
    "mimic": Command(c.MimicArgs, workflow.mimic, "expand source demos with Mimic (successes only)"),
    "train": Command(c.TrainArgs, workflow.train, "train a diffusion policy on a dataset"),
    "train-rl": Command(
        c.TrainRLArgs,
        rl.train_rl,
        "PPO (rsl_rl) on a task's dense reward: checkpoint, curve, resume point, tensorboard log",
    ),
    "split": Command(
        c.SplitArgs, datasets.split, "robomimic train/valid filter keys (mask/), or one dataset per phase (--out)"
    ),
    "export": Command(c.ExportArgs, datasets.export, "export a dataset to LeRobot v3"),
    "pipeline": Command(c.PipelineArgs, pipeline.pipeline, "Prefect flow: collect -> mimic -> train -> evaluate"),
    "view": Command(c.ViewArgs, datasets.view, "replay a recorded episode into rerun by re-applying its states"),
    "bench": Command(c.BenchArgs, bench.bench, "env-steps/s of the captured step vs the bare solver on the same model"),
    "bench-collect": Command(
        c.BenchCollectArgs,
        bench.bench_collect,
        "expert collection demos/s and per hour: physics / agent / writer seconds",
    ),
    "bench-train": Command(
        c.BenchTrainArgs, bench.bench_train, "diffusion-policy training steps/s: eager vs CUDA-graph step"
    ),
    "bench-refusals": Command(
        c.BenchRefusalsArgs,
        bench.bench_refusals,
        "each case of the bad-input table in a fresh newton-lab process: seconds to its refusal",
    ),
    "suite": Command(
        c.SuiteArgs,
        suite.suite,
        "every headline row of the results page, one product command each, records copied, page rebuilt",
    ),
    "results": Command(
        c.ResultsArgs,
        suite.results,
        "the results page's headline tables from the committed run records (--check: compare only)",
    ),
    "render": Command(c.RenderArgs, env.render, "one camera frame of a task as a PNG: RGB | depth | segmentation"),
    "teleop": Command(
        c.TeleopArgs,
        env.teleop,
        "drive a task from a teleop device (keyboard, replay, gp001, ...); keep / drop / exit each demo",
    ),
    "yolo-export": Command(
        c.YoloExportArgs,
        perception.yolo_export,
        "YOLO-seg dataset (images, polygon labels, data.yaml) of the sorting objects",
    ),
    "yolo-train": Command(
        c.YoloTrainArgs,
        perception.yolo_train,
        "train YOLO-seg (Ultralytics) on a yolo-export folder; mask mAP on a held-out export",
    ),
    "yolo-predict": Command(
        c.YoloPredictArgs,
        perception.yolo_predict,
        "a trained YOLO-seg model on fresh renders of the camera: overlay PNGs",
    ),
}
"""Subcommands in ``--help`` order."""
