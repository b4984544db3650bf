"""Arguments of the workflow's commands: collect, evaluate, mimic, train, split, export, view (``pipeline``: its own
module, ``commands.pipeline``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from .env import CameraArgs, RerunArgs, RolloutArgs, camera_option


@dataclass(kw_only=True)
class CollectArgs(CameraArgs, RerunArgs, RolloutArgs):
    """``newton-lab collect``: expert episodes of a task into a dataset."""

    dataset_path: str = "data/pick_cube_demos.hdf5"
    """Dataset to append to: .hdf5 / .h5 (robomimic layout) or .zarr."""
    save_end_scenario: str | None = None
    """write the final scene as a scenario YAML (needs --episodes 1 --num-envs 1)"""
    writer: Literal["auto", "thread", "process"] = "auto"
    """who writes the episodes: a thread of this process, or a process of its own that gets each step's ended
    episodes as one shared-memory block; auto: the process from 256 rows on"""
    domain_randomize: str | None = None
    """domain randomisation: AXIS=LEVEL,... (axes object_mass, object_size, friction, camera_shift, camera_tilt;
    LEVEL mild, strong or a number): each env row draws its own value up to LEVEL (factors: between 1/LEVEL and
    LEVEL), kept for the run and written into the dataset's provenance"""
    distractors: int = 0
    """objects no task term names, standing on the table (0 to 3: a teal can, a white block, a purple block),
    placed anew at every reset clear of the task's objects: demos among clutter. The dataset records the count;
    Mimic and replays rebuild its scene"""

    def env_kwargs(self) -> dict[str, Any]:
        """``CameraArgs.env_kwargs`` plus the scene's ``distractors``."""
        return {**super().env_kwargs(), "distractors": self.distractors}

    def domain_randomization(self) -> dict[str, float]:
        """``--domain-randomize`` as axis -> level (``task_api.perturbations.parse_randomization``; one-line
        errors); empty without it."""
        from ..task_api.perturbations import parse_randomization  # deferred: only this flag needs it (plain Python)

        return parse_randomization(self.domain_randomize) if self.domain_randomize is not None else {}

    def collect_kwargs(self) -> dict[str, Any]:
        """Keywords of ``env.collect(agent=..., **...)``."""
        return {
            **self.rollout_kwargs(),
            "path": self.dataset_path,
            "save_end_scenario": self.save_end_scenario,
            "writer": self.writer,
        }


@dataclass(kw_only=True)
class EvaluateArgs(CameraArgs, RerunArgs, RolloutArgs):
    """``newton-lab evaluate``: success rate of a policy checkpoint, or of the task's expert."""

    checkpoint: str | None = None
    """policy checkpoint; the expert planner when omitted"""
    phase_checkpoint: list[str] | None = None
    """a coherent task's phase policies, PHASE=CHECKPOINT each (e.g. pick=pick.pt place=place.pt), or one per target
    of a kind, KIND/TARGET=CHECKPOINT (e.g. pick/red_cube=red.pt, one for each target); the phases without one run
    their component's expert"""
    perturb: str | None = None
    """evaluate under perturbations: AXIS=LEVEL,... together (LEVEL mild, strong or a number; axes action_noise,
    action_latency, posture_noise, object_mass, object_size, friction, distractors, camera_shift, camera_tilt,
    camera_fov, surface_texture, light_intensity, light_direction), or sweep: unperturbed, then each axis at each
    level alone (one row each)"""

    eager_policy: bool = False
    """sample a diffusion policy's actions eagerly instead of from CUDA graphs (on a GPU; the record's timing then
    gives the other side of the A/B)"""
    run_record: str | None = None
    """write the run record (JSON) here; with --perturb one is written anyway, by default to
    outputs/records/evaluate-<task>-<UTC time>.json"""

    def perturbation_cells(self):
        """The evaluations ``--perturb`` asks for (``task_api.perturbations.Cell``; one-line errors)."""
        from ..task_api.perturbations import parse_cells  # deferred: only --perturb needs it (plain Python)

        return parse_cells(self.perturb) if self.perturb is not None else []

    def policy_device(self) -> str:
        """Torch device of the evaluated policies: the env's CUDA device (the policy runs beside it; with no
        ``--device``, Warp's default device), else cpu."""
        device = self.device
        if device is None:
            import warp as wp  # deferred: only the evaluation asks, and it builds a Warp env right after

            default = wp.get_device()
            device = f"cuda:{default.ordinal}" if default.is_cuda else "cpu"
        return device if device.startswith("cuda") else "cpu"

    def phase_checkpoints(self) -> dict[str, str]:
        """``--phase-checkpoint`` as phase name -> checkpoint path (one-line error for a malformed entry)."""
        out: dict[str, str] = {}
        for item in self.phase_checkpoint or []:
            phase, sep, path = item.partition("=")
            if not sep or not phase or not path:
                raise ValueError(f"--phase-checkpoint {item!r}: write PHASE=CHECKPOINT, e.g. pick=outputs/pick.pt")
            if phase in out:
                raise ValueError(f"--phase-checkpoint names phase {phase!r} twice; give one checkpoint per phase")
            out[phase] = path
        return out


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

    def mimic_kwargs(self) -> dict[str, Any]:
        """Keywords of ``mimic(self.dataset_path, **...)``."""
        return {
            "episodes": self.episodes,
            "num_envs": self.num_envs,
            "output_path": self.output_path,
            "seed": self.seed,
            "device": self.device,
            "max_attempts": self.max_attempts,
            "progress": not self.no_progress,
            "cameras": camera_option(self.cameras),
        }


TRAIN_OVERRIDES = (
    "epochs",
    "batch_size",
    "max_steps",
    "lr",
    "weight_decay",
    "num_workers",
    "time_budget_s",
    "init_checkpoint",
    "prediction_type",
    "compile",
    "bf16",
    "cudnn_benchmark",
    "bf16_norms",
    "obs_min_range",
)
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
    image_keys: str | None = None
    """comma-separated camera terms the policy sees (e.g. front_head_rgb,left_wrist_rgb; default: the preset's)"""
    instruction_keys: str | None = None
    """comma-separated low-dim terms that are the task's instruction (e.g. sorting_object): with --image-keys
    they condition the camera trunks too (FiLM)"""
    prediction_type: Literal["epsilon", "sample"] | None = None
    """what the U-Net predicts: epsilon (the noise; presets' default) or sample (the clean actions; learns
    PickCube in fewer steps, the demo's choice)"""
    obs_min_range: float | None = None
    """narrowest window of the observation normaliser [m, rad] (default 0.01; 0: plain min-max, which turns a
    deviation in a dimension that barely moved in the demos into values far outside [-1, 1])"""
    init_checkpoint: str | None = None
    """continue training this checkpoint (its architecture and normalisers are kept)"""
    compile: bool | None = None
    """run the network through torch.compile (CPU: about a minute of compiling, then faster steps)"""
    bf16: bool | None = None
    """forward and backward under bfloat16 autocast (weights, optimiser state stay float32)"""
    bf16_norms: bool | None = None
    """with --bf16, the GroupNorms run in bfloat16 too (CUDA autocast otherwise runs each in float32)"""
    cudnn_benchmark: bool | None = None
    """on CUDA, cuDNN times its convolution algorithms for the fixed shapes once and keeps the fastest"""
    time_budget_s: float | None = None
    """wall-clock budget [s]: the run is shortened to fit (LR schedule re-planned)"""
    device: str = "cpu"
    """Torch device for training (cpu, cuda, cuda:1, ...)."""
    gpus: int = 1
    """data-parallel processes, one GPU each (torchrun + NCCL; --batch-size is per GPU); with --device cpu,
    that many gloo processes"""
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
        for key in ("obs_keys", "image_keys", "instruction_keys"):
            if getattr(self, key):
                cfg[key] = tuple(k.strip() for k in getattr(self, key).split(",") if k.strip())
        return cfg


@dataclass(kw_only=True)
class SplitArgs:
    """``newton-lab split``: robomimic train / valid filter keys (``mask/``), or one dataset per phase (``--out``)."""

    dataset_path: str
    """Dataset to split (by phase: a coherent task's, its episodes record datagen/phase)."""
    out: str | None = None
    """split by phase into this folder (<phase>.hdf5 / .zarr, must not exist); default: write filter keys"""
    phases: str | None = None
    """with --out: comma-separated phases to write (default: every phase)"""
    val_ratio: float = 0.1
    """Fraction of the demos put in mask/valid (robomimic's --ratio)."""
    filter_key: str | None = None
    """split only this filter key's demos (e.g. successful) into <key>_train / <key>_valid"""
    seed: int = 0
    """Seed of the train / valid shuffle (robomimic's split_train_val uses 0)."""

    def phase_names(self) -> list[str] | None:
        """``--phases`` as a list of names; None when not given (every phase)."""
        return [p.strip() for p in self.phases.split(",") if p.strip()] if self.phases else None


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
