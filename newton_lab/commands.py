"""The argument model: one ``@dataclass`` per command, shared by the console script (``newton_lab.cli``
generates its argparse parser from these classes: fields -> flags, field docstrings -> help), the examples
(``newton_lab.cli.parse_args`` with their own defaults) and the Prefect stages (``newton_lab.flows``).

A field ``num_envs`` is the flag ``--num-envs``; ``bool`` fields are switches; ``X | None`` fields are
optional; fields without a default are required; ``list[str]`` fields take one or more values; field
metadata may set ``flags`` (the spellings, default ``--field-name``) or ``positional``. Methods turn an
argument object into the keywords of the library call it drives (``make_env``, ``env.collect``, ``mimic``,
``Policy.train``, ``run_pipeline``), so no caller re-lists them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from .task_api.cfg import parse_cameras
from .task_api.registry import DEFAULT_TASK_ID

TASK_OPTION_FIELDS = ("sorting_object", "init_scenario")
"""``EnvArgs`` fields that are task options (``make_env(..., task_options=...)``)."""


@dataclass(kw_only=True)
class EnvArgs:
    """Which task, how many rows, where, how seeded: everything ``make_env`` takes."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    num_envs: int = 1
    """Parallel env rows (worlds) stepped as one batch."""
    device: str | None = None
    """Warp device, e.g. cpu or cuda:0 (default: Warp's)"""
    seed: int = 0
    """Seed of the reset randomisation (per row and episode)."""
    randomize: bool = False
    """turn on the task's reset randomisation"""
    sorting_object: str | None = None
    """SortToShelf tasks: the object to sort"""
    init_scenario: str | None = None
    """component tasks: start from this scenario YAML"""

    def task_options(self) -> dict[str, Any]:
        """Task options that were given (unset ones are left to the task's defaults)."""
        return {k: getattr(self, k) for k in TASK_OPTION_FIELDS if getattr(self, k) is not None}

    def env_kwargs(self) -> dict[str, Any]:
        """Keywords of ``make_env(self.task, **...)``."""
        return {"num_envs": self.num_envs, "device": self.device, "seed": self.seed, "randomize": self.randomize,
                "task_options": self.task_options()}


@dataclass(kw_only=True)
class RolloutArgs(EnvArgs):
    """An env plus how long to run it: ``env.collect`` / ``env.evaluate``."""

    episodes: int = 1
    """Episodes to run (over all rows)."""
    max_steps: int = 1000
    """episode step limit of the loop [control steps]"""
    no_progress: bool = False
    """No progress bar."""
    headless: bool = False
    """accepted for compatibility; newton-lab never opens a window"""

    def rollout_kwargs(self) -> dict[str, Any]:
        """Keywords shared by ``env.collect`` and ``env.evaluate``."""
        return {"episodes": self.episodes, "max_steps": self.max_steps, "progress": not self.no_progress}


@dataclass(kw_only=True)
class RerunArgs:
    """Streaming a run to the rerun viewer."""

    rerun: bool = False
    """stream to a rerun viewer (spawned)"""
    rerun_save: str | None = None
    """record the run to this .rrd file (headless)"""
    rerun_worlds: int = 4
    """rows drawn in rerun"""
    rerun_image_every: int = 1
    """log the cameras' images to rerun every n-th step (each logged image step renders: CPU time)"""


def camera_option(value: str | None) -> bool | dict[str, Any] | None:
    """``--cameras`` as ``make_env(cameras=...)``: ``default`` -> None (the task's cameras), ``none`` -> False (no
    rendering), else ``task_api.cfg.parse_cameras(value)``; a bad spelling raises a one-line error."""
    return None if value in (None, "default") else False if value == "none" else parse_cameras(value)


@dataclass(kw_only=True)
class CameraArgs:
    cameras: str = "default"
    """image terms: default (the task's cameras; mimic: the source dataset's), none (state only: nothing is
    rendered) or <camera>=<W>x<H>[:<data>+...][,...] (e.g. front_head=96x72, or front_head=96x72:rgb to record
    RGB only; data: rgb, depth, segmentation)"""

    def env_kwargs(self) -> dict[str, Any]:
        """``EnvArgs.env_kwargs`` plus ``cameras``."""
        return {**super().env_kwargs(), "cameras": camera_option(self.cameras)}  # type: ignore[misc]


@dataclass(kw_only=True)
class TasksArgs:
    """``newton-lab tasks``: no arguments."""


@dataclass(kw_only=True)
class CollectArgs(CameraArgs, RerunArgs, RolloutArgs):
    """``newton-lab collect``: expert episodes of a task into a dataset."""

    dataset_path: str = "data/pick_cube_demos.hdf5"
    """Dataset to append to: .hdf5 / .h5 (robomimic layout) or .zarr."""
    save_end_scenario: str | None = None
    """write the final scene as a scenario YAML (needs --episodes 1 --num-envs 1)"""

    def collect_kwargs(self) -> dict[str, Any]:
        """Keywords of ``env.collect(agent=..., **...)``."""
        return {**self.rollout_kwargs(), "path": self.dataset_path, "save_end_scenario": self.save_end_scenario}


@dataclass(kw_only=True)
class EvaluateArgs(CameraArgs, RerunArgs, RolloutArgs):
    """``newton-lab evaluate``: success rate of a policy checkpoint, or of the task's expert."""

    checkpoint: str | None = None
    """policy checkpoint; the expert planner when omitted"""


@dataclass(kw_only=True)
class MimicArgs(CameraArgs):
    """``newton-lab mimic``: expand source demos with Mimic (successes only)."""

    dataset_path: str
    """Source dataset (expert demos of a task with a Mimic variant)."""
    output_path: str | None = None
    """Dataset the generated demos are appended to (default: <source stem>_mimic<suffix> beside the source)."""
    episodes: int = 36
    """Successful demos to generate."""
    num_envs: int = 8
    """Parallel env rows generating at once."""
    max_attempts: int | None = None
    """Give up after this many attempts (default 10 x --episodes)."""
    seed: int = 1
    """Seed of the scene randomisation and the source-segment choice."""
    device: str | None = None
    """Warp device, e.g. cpu or cuda:0 (default: Warp's)"""
    no_progress: bool = False
    """No progress bar."""
    headless: bool = False
    """accepted for compatibility; newton-lab never opens a window"""

    def mimic_kwargs(self) -> dict[str, Any]:
        """Keywords of ``mimic(self.dataset_path, **...)``."""
        return {"episodes": self.episodes, "num_envs": self.num_envs, "output_path": self.output_path,
                "seed": self.seed, "device": self.device, "max_attempts": self.max_attempts,
                "progress": not self.no_progress, "cameras": camera_option(self.cameras)}


TRAIN_OVERRIDES = ("epochs", "batch_size", "max_steps", "lr", "weight_decay", "num_workers", "time_budget_s",
                   "init_checkpoint", "prediction_type", "compile", "bf16")
"""``TrainArgs`` fields that override the preset only when given."""


@dataclass(kw_only=True)
class TrainArgs:
    """``newton-lab train``: a diffusion policy on one or more datasets of one task."""

    dataset_path: list[str]
    """one dataset, or several of the same task trained as one"""
    output_dir: str = "outputs/policy"
    """Folder for checkpoint.pt and train_log.json."""
    preset: str = "default"
    """named settings: default (state, GPU), cpu (state, 2 cores), vision (RGB + proprioception), vision_cpu"""
    epochs: int | None = None
    """passes over the data (default 100)"""
    max_steps: int | None = None
    """Cap on gradient steps."""
    batch_size: int | None = None
    """default 256 (cpu preset: 64)"""
    lr: float | None = field(default=None, metadata={"flags": ("--lr", "--learning-rate")})
    """peak learning rate (default 1e-4; cpu preset: 6e-4)"""
    weight_decay: float | None = None
    """AdamW weight decay (default 1e-6)."""
    num_workers: int | None = field(default=None, metadata={"flags": ("--num-data-workers",)})
    """DataLoader worker processes (default 0: the data is in memory)."""
    obs_keys: str | None = None
    """comma-separated obs terms to condition on (default: every low-dim term but actions)"""
    prediction_type: Literal["epsilon", "sample"] | None = None
    """what the U-Net predicts: epsilon (the noise; presets' default) or sample (the clean actions; learns
    PickCube in fewer steps, the demo's choice)"""
    init_checkpoint: str | None = None
    """continue training this checkpoint (its architecture and normalisers are kept)"""
    compile: bool | None = None
    """run the network through torch.compile (CPU: about a minute of compiling, then faster steps)"""
    bf16: bool | None = None
    """forward and backward under bfloat16 autocast (weights, optimiser state stay float32)"""
    time_budget_s: float | None = None
    """wall-clock budget [s]: the run is shortened to fit (LR schedule re-planned)"""
    device: str = "cpu"
    """Torch device for training (cpu, cuda, cuda:1, ...)."""
    seed: int = 0
    """Seed of weight init, batch order and diffusion noise."""
    resume: bool = False
    """continue the interrupted run in --output-dir from its resume.pt (same datasets and settings)"""
    checkpoint_every_steps: int | None = None
    """write --output-dir/resume.pt every N steps (default 500)"""
    checkpoint_every_s: float | None = None
    """write --output-dir/resume.pt every N seconds too (default 300)"""

    def datasets(self) -> str | list[str]:
        """The dataset argument of ``Policy.train``: one path, or the list of several."""
        return self.dataset_path[0] if len(self.dataset_path) == 1 else list(self.dataset_path)

    def train_cfg(self, presets: dict[str, dict[str, Any]]) -> dict[str, Any]:
        """The training config: the named preset (of ``presets``), then every field that was given."""
        if self.preset not in presets:
            raise ValueError(f"unknown training preset {self.preset!r}; valid presets: {sorted(presets)}")
        cfg = dict(presets[self.preset], device=self.device, seed=self.seed, output_dir=self.output_dir)
        given = (*TRAIN_OVERRIDES, "checkpoint_every_steps", "checkpoint_every_s")
        cfg.update({k: getattr(self, k) for k in given if getattr(self, k) is not None})
        if self.obs_keys:
            cfg["obs_keys"] = tuple(k.strip() for k in self.obs_keys.split(",") if k.strip())
        return cfg


@dataclass(kw_only=True)
class SplitArgs:
    """``newton-lab split``: robomimic train / valid filter keys (``mask/``), or one dataset per phase (``--out``)."""

    dataset_path: str
    """Dataset to split (by phase: a coherent task's, its episodes record datagen/phase)."""
    out: str | None = None
    """split by phase into this folder (<phase>.hdf5 / .zarr, must not exist); default: write filter keys"""
    val_ratio: float = 0.1
    """Fraction of the demos put in mask/valid (robomimic's --ratio)."""
    filter_key: str | None = None
    """split only this filter key's demos (e.g. successful) into <key>_train / <key>_valid"""
    seed: int = 0
    """Seed of the train / valid shuffle (robomimic's split_train_val uses 0)."""


@dataclass(kw_only=True)
class ExportArgs:
    """``newton-lab export``: a dataset as a LeRobot v3 dataset."""

    dataset_path: str
    """Dataset to export."""
    root: str
    """new LeRobot dataset folder (must not exist)"""
    include_failed: bool = False
    """Export failed episodes too."""
    no_video: bool = False
    """Camera streams as lossless PNG image features instead of mp4 (AV1) video features."""


RECIPE_FIELDS = ("demos", "mimic_episodes", "eval_episodes", "num_envs")
"""``PipelineArgs`` counts that default to the demo recipe's (``newton_lab.flows.settings.DEMO_RECIPES``)."""


@dataclass(kw_only=True)
class PipelineArgs:
    """``newton-lab pipeline``: the Prefect flow collect -> mimic -> train -> evaluate."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    recipe: Literal["auto", "cpu", "gpu"] = "auto"
    """counts and training of every flag left unset: cpu (2-core budget), gpu (full size), auto (gpu when torch
    sees a CUDA device and --device is not cpu)"""
    demos: int | None = None
    """expert demos collected (cpu recipe 4, gpu 10)"""
    mimic_episodes: int | None = None
    """demos generated by Mimic from the expert demos (cpu recipe 100, gpu 500)"""
    train_steps: int | None = None
    """gradient steps (cpu recipe 3000, gpu 10000)"""
    eval_episodes: int | None = None
    """evaluation episodes of the trained policy (cpu recipe 20, gpu 100)"""
    num_envs: int | None = None
    """parallel env rows of collection, Mimic and evaluation (cpu recipe 4, gpu 50)"""
    device: str | None = None
    """Warp device of the envs and torch device of training, e.g. cpu or cuda:0 (default: cpu for the cpu
    recipe; Warp's and cuda for the gpu recipe)"""
    seed: int = 0
    """Base seed: Mimic uses seed + 1, evaluation seed + 10000."""
    out: str = "outputs/pipeline"
    """Output folder: artifacts, manifests, metrics.json, Prefect state."""
    runner: str = "local"
    """local or dask"""
    workers: int = 1
    """Dask shards of collection, Mimic and evaluation, and local worker processes (on a CUDA host with no
    --device or --device cuda: one worker per GPU, at most this many)."""
    address: str | None = None
    """Dask scheduler address (default: start a local cluster)"""
    retries: int = 1
    """retries of a failed stage"""

    def train_cfg(self, recipe: dict[str, Any]) -> dict[str, Any]:
        """The resolved ``recipe``'s training config on its training device, with ``train_steps`` when given."""
        cfg = dict(recipe["train"], device=recipe["train_device"])
        if self.train_steps:
            cfg["max_steps"] = self.train_steps
        return cfg

    def pipeline_kwargs(self, recipe: dict[str, Any]) -> dict[str, Any]:
        """Keywords of ``newton_lab.flows.orchestration.run_pipeline``: the given fields, and for the unset ones
        those of ``recipe`` (``newton_lab.flows.settings.demo_recipe(self.recipe, self.device)``)."""
        counts = {k: recipe[k] if getattr(self, k) is None else getattr(self, k) for k in RECIPE_FIELDS}
        return {"runner": self.runner, "workers": self.workers, "address": self.address, "retries": self.retries,
                "task_id": self.task, "train_cfg": self.train_cfg(recipe), "device": recipe["device"],
                "out": str(Path(self.out).resolve()), "seed": self.seed, **counts}


@dataclass(kw_only=True)
class ViewArgs:
    """``newton-lab view``: replay a recorded episode into rerun by re-applying its states."""

    dataset: str = field(metadata={"positional": True})
    """Dataset holding the episode."""
    episode: int = 0
    """Demo id to replay."""
    save: str | None = None
    """.rrd file to write"""
    spawn: bool = False
    """open a rerun viewer"""


@dataclass(kw_only=True)
class BenchArgs:
    """``newton-lab bench``: env-steps/s of the captured step vs the bare solver on the same model."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    num_envs: int = 4
    """Parallel env rows."""
    steps: int = 200
    """Env steps timed."""
    device: str | None = None
    """Warp device, e.g. cpu or cuda:0 (default: Warp's)"""
    camera: str | None = None
    """also time the step with this G1 camera rendered every step (front_head, left_wrist, right_wrist)"""
    resolution: list[int] | None = None
    """camera image width and height [px] (default 128 128)"""
    camera_data: list[str] | None = None
    """camera outputs: rgb, depth, segmentation (default rgb)"""


@dataclass(kw_only=True)
class BenchCollectArgs:
    """``newton-lab bench-collect``: expert collection throughput, seconds split into physics / agent / writer."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    num_envs: int = 4
    """Parallel env rows."""
    episodes: int = 16
    """Successful demos to collect (after a first-use run of one episode per row)."""
    device: str | None = None
    """Warp device, e.g. cpu or cuda:0 (default: Warp's)"""
    dataset_path: str = "outputs/bench_collect.zarr"
    """Fresh dataset to write (.zarr or .hdf5); the first-use and prefilled runs write beside it."""
    prefill: int = 10_000
    """Episodes stored before the second run, which appends to that full dataset (0: skip it)."""


@dataclass(kw_only=True)
class BenchTrainArgs:
    """``newton-lab bench-train``: diffusion-policy training steps/s, eager vs CUDA-graph step."""

    dataset_path: str
    """Dataset the batches are drawn from."""
    batch_size: int = 1024
    """Windows per training step."""
    steps: int = 200
    """Training steps timed per variant."""
    preset: Literal["default", "cpu", "vision", "vision_cpu"] = "default"
    """Named training settings (network size)."""
    bf16: bool = False
    """also time the steps under bfloat16 autocast (float32 and bf16 side by side)"""
    device: str = "cpu"
    """Torch device (cpu, cuda, cuda:1, ...)."""


@dataclass(kw_only=True)
class RenderArgs(EnvArgs):
    """``newton-lab render``: one camera frame of a task as a PNG, RGB | depth | segmentation side by side."""

    camera: str = "front_head"
    """G1 camera: front_head, left_wrist or right_wrist"""
    resolution: list[int] | None = None
    """image width and height [px] (default: the task's, else 298 224)"""
    randomize: bool = True
    """turn on the task's reset randomisation and the cameras' (colours, brightness, pose jitter), seeded by --seed"""
    expert_steps: int = 0
    """run the task's expert this many control steps before the frame"""
    out: str = "render.png"
    """PNG file to write"""
