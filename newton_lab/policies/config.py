"""Diffusion-policy settings: ``DiffusionPolicyConfig`` (architecture, diffusion, training; per-field docs) and
the named ``PRESETS``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from .model import ACTIVATIONS
from .scheduler import PREDICTION_TYPES

PROPRIOCEPTION = ("robot_joint_pos", "gripper_pos")
"""The privileged-free low-dim terms of the visuomotor presets: what the robot itself measures (joint positions,
gripper opening), no object or target pose; the scene reaches the policy only through its cameras."""

PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    # A 2-core CPU budget (~18 min): a quarter-width U-Net, small batches, a higher learning rate, 10k steps.
    "cpu": {
        "down_dims": (32, 64, 128),
        "diffusion_step_embed_dim": 64,
        "batch_size": 64,
        "lr": 6e-4,
        "warmup_steps": 300,
        "max_steps": 10000,
        "epochs": 1000,
    },
    # Visuomotor (front-head RGB + proprioception, no object pose): the full ResNet-18/GroupNorm trunk, on a GPU.
    "vision": {
        "image_keys": ("front_head_rgb",),
        "obs_keys": PROPRIOCEPTION,
        "prediction_type": "sample",
        "num_inference_steps": 5,
    },
    # Visuomotor on 2 CPU cores (96x72 frames): a quarter-width ResNet-18 trunk, proprioception only.
    "vision_cpu": {
        "down_dims": (32, 64, 128),
        "diffusion_step_embed_dim": 64,
        "batch_size": 32,
        "lr": 6e-4,
        "warmup_steps": 100,
        "max_steps": 3000,
        "epochs": 1000,
        "encoder_width": 16,
        "image_feature_dim": 32,
        "image_keys": ("front_head_rgb",),
        "obs_keys": PROPRIOCEPTION,
        "prediction_type": "sample",
        "num_inference_steps": 5,
    },
}
"""Named training settings; explicit fields override a preset's."""

ARCHITECTURE_FIELDS = (
    "obs_horizon",
    "action_horizon",
    "pred_horizon",
    "down_dims",
    "kernel_size",
    "n_groups",
    "diffusion_step_embed_dim",
    "activation",
    "num_train_timesteps",
    "num_inference_steps",
    "prediction_type",
    "obs_keys",
    "image_keys",
    "crop",
    "image_feature_dim",
    "encoder_width",
    "instruction_keys",
)
"""Config fields a checkpoint fixes: fine-tuning from it keeps them."""


def _names(value: str | tuple[str, ...] | list[str] | None) -> tuple[str, ...] | None:
    """A name or names as a tuple; None for none."""
    if isinstance(value, str):
        value = (value,)
    return tuple(value) if value else None


@dataclass(kw_only=True)
class DiffusionPolicyConfig:
    """Architecture, diffusion and training settings (defaults: ManiSkill / Chi et al. state-based DP)."""

    obs_horizon: int = 2
    """Observation steps (current + past) flattened into the FiLM global condition."""
    action_horizon: int = 8
    """Actions executed per prediction (receding horizon); at most pred_horizon - obs_horizon + 1."""
    pred_horizon: int = 16
    """Actions denoised per prediction; divisible by 2 ** (len(down_dims) - 1)."""
    down_dims: tuple[int, ...] = (64, 128, 256)
    """U-Net channel widths per level, multiples of n_groups; one downsampling between levels."""
    kernel_size: int = 5
    """Temporal conv kernel size (odd)."""
    n_groups: int = 8
    """GroupNorm groups in every conv block."""
    diffusion_step_embed_dim: int = 128
    """Width of the sinusoidal diffusion-step embedding (then an MLP)."""
    activation: str = "mish"
    """Activation of every U-Net block: "mish" (Chi et al.) or "silu" (cheaper on CPU, see ``model.ACTIVATIONS``)."""
    num_train_timesteps: int = 100
    """DDPM noising steps (squaredcos_cap_v2 betas, samples clipped to [-1, 1])."""
    num_inference_steps: int = 10
    """DDIM denoising steps at inference (eta 0)."""
    prediction_type: str = "epsilon"
    """What the U-Net predicts: "epsilon" (the noise, Chi et al.) or "sample" (the clean actions x0; on
    PickCube it succeeds after 3k steps where epsilon needs about 10k, see benchmarks history, "Policies")."""
    lr: float = 1e-4
    """AdamW peak learning rate."""
    weight_decay: float = 1e-6
    """AdamW weight decay."""
    betas: tuple[float, float] = (0.95, 0.999)
    """AdamW betas."""
    warmup_steps: int = 500
    """Linear LR warm-up steps before the cosine decay to 0."""
    ema_power: float = 0.75
    """EMA warm-up power: decay_k = 1 - (1 + k) ** -ema_power (capped at 0.9999)."""
    batch_size: int = 256
    """Windows per optimiser step (a dataset with fewer windows is repeated to fill one batch per epoch)."""
    epochs: int = 100
    """Passes over all windows."""
    max_steps: int | None = None
    """Optional cap on optimiser steps (stops mid-epoch)."""
    init_checkpoint: str | None = None
    """Continue from this checkpoint (fine-tuning / training across sessions): its weights, normalisers,
    observation keys and architecture are kept; this config's training fields (lr, steps, ...) apply."""
    time_budget_s: float | None = None
    """Optional wall-clock budget [s] for the optimiser loop: the step rate is measured over the first 50 steps and
    the run is shortened to fit, with the cosine schedule re-planned so the LR still decays to 0."""
    cuda_graph: bool = True
    """On CUDA, capture the whole training step once and replay it (1.7x the eager steps/s on an H100 at batch
    1024); off = the eager step."""
    bf16: bool = False
    """Run the networks' forward and backward under bfloat16 autocast (encoder convolutions, U-Net); weights,
    optimiser state, normalisers and the loss stay float32."""
    bf16_norms: bool = False
    """With ``bf16``, the GroupNorms run in bfloat16 too (``policies.norm``): CUDA autocast otherwise runs each in
    float32, casting every activation up and back down around it. ``bench-train --bf16-norms`` measures both."""
    cudnn_benchmark: bool = False
    """On CUDA, let cuDNN time its convolution algorithms for the step's fixed shapes once and keep the fastest
    (``torch.backends.cudnn.benchmark``); ``bench-train --cudnn-benchmark`` measures both sides."""
    compile: bool = False
    """The network runs through ``torch.compile``: about a minute of compiling on 2 CPU cores, then each step takes
    ~0.55x the time (the quarter-width U-Net on CPU is bound by per-op overhead, which the compiled kernels fuse
    away). On CUDA the captured step records the compiled kernels (compiled in its warm-up steps; ``bench-train
    --compile`` times both steps). Weights, checkpoints and RNG draws are unchanged."""
    num_workers: int = 0
    """DataLoader worker processes (data is in memory: 0 is usually fastest)."""
    seed: int = 0
    """Seed for weight init, batch order and diffusion noise."""
    device: str = "cpu"
    """Torch device for training ("cpu", "cuda", "cuda:1", ...)."""
    obs_keys: tuple[str, ...] | None = None
    """obs/<term> arrays to condition on; None = every low-dim term except ``actions``."""
    obs_min_range: float = 0.01
    """Narrowest window [obs units: m, rad] of the low-dim observations' min-max normaliser, centred on the data.
    A dimension that barely moved in the demos would otherwise amplify any deviation at inference: in
    SortToShelf's place phase the base's x and y vary by 0.14 and 0.41 mm over the expert demos, so a base 1 mm
    off at inference maps to 15 and 6 instead of inside [-1, 1]. 0 = the plain min-max (checkpoints before this
    field)."""
    image_keys: tuple[str, ...] | None = None
    """Camera image terms to condition on (e.g. ("front_head_rgb",)): RGB frames through ``vision.ImageEncoder``;
    None = a state-based policy."""
    crop: float = 0.9
    """Fraction of each image side kept by the crop (random position in training, centre at inference)."""
    image_feature_dim: int = 64
    """Features per camera (after the spatial-softmax keypoints)."""
    encoder_width: int = 64
    """Base width of the ResNet-18 trunk (64 = ResNet-18; 16 for CPU training)."""
    instruction_keys: tuple[str, ...] | None = None
    """Low-dim terms among the observed ones that are the task's instruction (e.g. SortToShelf-All's
    ``sorting_object`` one-hot, the object a phase acts on): besides the U-Net's condition they FiLM-condition every
    residual block of the image trunks (``vision``), so what the cameras report depends on which object is meant.
    None = trunks see images alone (checkpoints before this field)."""
    success_only: bool = True
    """Train only on demos marked successful."""
    output_dir: str = "outputs/policies/diffusion"
    """Where train() writes checkpoint.pt and train_log.json."""
    progress: bool = True
    """Show progress while training: a tqdm bar in a terminal, else a plain line every 30 s."""
    checkpoint_every_steps: int | None = 500
    """Write the resume file ``<output_dir>/resume.pt`` every this many optimiser steps (None: not by steps)."""
    checkpoint_every_s: float | None = 300.0
    """Also write it when this many seconds passed since the last one (None: not by time); a killed run then
    continues from it with ``train(..., resume=True)`` / ``newton-lab train --resume``."""

    def __post_init__(self) -> None:
        self.down_dims = tuple(int(d) for d in self.down_dims)
        self.betas = tuple(float(b) for b in self.betas)
        if isinstance(self.obs_keys, str):
            self.obs_keys = (self.obs_keys,)
        self.obs_keys = None if self.obs_keys is None else tuple(self.obs_keys)
        self.image_keys, self.instruction_keys = _names(self.image_keys), _names(self.instruction_keys)
        self.output_dir = str(self.output_dir)
        for ok, message in self._checks():
            if not ok:
                raise ValueError(f"DiffusionPolicyConfig: {message}")

    def _checks(self) -> list[tuple[bool, str]]:
        """(holds, what is wrong otherwise) for every constraint between the fields."""
        levels = len(self.down_dims)
        return [
            (self.obs_horizon >= 1, f"obs_horizon must be >= 1, got {self.obs_horizon}"),
            (
                1 <= self.action_horizon <= self.pred_horizon - self.obs_horizon + 1,
                f"action_horizon must be in 1..pred_horizon - obs_horizon + 1 = "
                f"{self.pred_horizon - self.obs_horizon + 1}, got {self.action_horizon}",
            ),
            (
                levels >= 1 and all(d > 0 and d % self.n_groups == 0 for d in self.down_dims),
                f"down_dims must be positive multiples of n_groups={self.n_groups}, got {self.down_dims}",
            ),
            (
                self.pred_horizon % 2 ** (levels - 1) == 0,
                f"pred_horizon must be divisible by 2 ** (len(down_dims) - 1) = {2 ** (levels - 1)}, "
                f"got {self.pred_horizon}",
            ),
            (self.kernel_size % 2 == 1, f"kernel_size must be odd, got {self.kernel_size}"),
            (
                1 <= self.num_inference_steps <= self.num_train_timesteps,
                f"num_inference_steps must be in 1..num_train_timesteps={self.num_train_timesteps}, "
                f"got {self.num_inference_steps}",
            ),
            (
                self.activation in ACTIVATIONS,
                f"activation must be one of {', '.join(ACTIVATIONS)}, got {self.activation!r}",
            ),
            (
                self.prediction_type in PREDICTION_TYPES,
                f"prediction_type must be one of {', '.join(PREDICTION_TYPES)}, got {self.prediction_type!r}",
            ),
            (len(self.betas) == 2, f"betas must be a pair, got {self.betas}"),
            (0.0 < self.crop <= 1.0, f"crop must be in (0, 1], got {self.crop}"),
            (
                not self.instruction_keys or bool(self.image_keys),
                f"instruction_keys {list(self.instruction_keys or ())} condition the image trunks; give image_keys "
                "too, or leave them to obs_keys alone",
            ),
            (
                not self.instruction_keys or self.obs_keys is None or set(self.instruction_keys) <= set(self.obs_keys),
                f"instruction_keys {list(self.instruction_keys or ())} must be among obs_keys "
                f"{list(self.obs_keys or ())}",
            ),
            (self.obs_min_range >= 0.0, f"obs_min_range must be >= 0, got {self.obs_min_range}"),
            (
                self.image_feature_dim >= 1 and self.encoder_width >= 16,
                f"image_feature_dim must be >= 1 and encoder_width >= 16, got {self.image_feature_dim} and "
                f"{self.encoder_width}",
            ),
            (
                self.batch_size >= 1 and self.epochs >= 1,
                f"batch_size and epochs must be >= 1, got {self.batch_size} and {self.epochs}",
            ),
            (self.max_steps is None or self.max_steps >= 1, f"max_steps must be None or >= 1, got {self.max_steps}"),
            (
                self.time_budget_s is None or self.time_budget_s > 0,
                f"time_budget_s must be None or > 0, got {self.time_budget_s}",
            ),
            (
                self.checkpoint_every_steps is None or self.checkpoint_every_steps >= 1,
                f"checkpoint_every_steps must be None or >= 1, got {self.checkpoint_every_steps}",
            ),
            (
                self.checkpoint_every_s is None or self.checkpoint_every_s > 0,
                f"checkpoint_every_s must be None or > 0, got {self.checkpoint_every_s}",
            ),
            (
                self.warmup_steps >= 0 and self.num_workers >= 0,
                f"warmup_steps and num_workers must be >= 0, got {self.warmup_steps} and {self.num_workers}",
            ),
        ]

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> DiffusionPolicyConfig:
        """Build from a plain dict; unknown keys raise ValueError listing the valid ones."""
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ValueError(f"unknown DiffusionPolicyConfig key(s) {unknown}; valid keys: {', '.join(names)}")
        return cls(**values)

    def with_architecture_of(self, other: DiffusionPolicyConfig) -> DiffusionPolicyConfig:
        """This config with ``other``'s architecture, horizons, diffusion settings and obs keys."""
        return dataclasses.replace(self, **{k: getattr(other, k) for k in ARCHITECTURE_FIELDS})

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly dict (tuples as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}
