"""Diffusion Policy (Chi et al. 2023, CNN variant) for low-dim observations: config, model wrapper, checkpoints."""

from __future__ import annotations

import dataclasses
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from .ema import EMA
from .model import ACTIVATIONS, ConditionalUnet1D
from .normalize import MinMaxNormalizer
from .scheduler import PREDICTION_TYPES, NoiseScheduler

PRESETS: dict[str, dict[str, Any]] = {
    "default": {},
    # A 2-core CPU budget (~18 min): a quarter-width U-Net, small batches, a higher learning rate, 10k steps.
    "cpu": {"down_dims": (32, 64, 128), "diffusion_step_embed_dim": 64, "batch_size": 64, "lr": 6e-4,
            "warmup_steps": 300, "max_steps": 10000, "epochs": 1000},
}
"""Named training settings; explicit fields override a preset's."""

ARCHITECTURE_FIELDS = ("obs_horizon", "action_horizon", "pred_horizon", "down_dims", "kernel_size", "n_groups",
                       "diffusion_step_embed_dim", "activation", "num_train_timesteps", "num_inference_steps",
                       "prediction_type", "obs_keys")
"""Config fields a checkpoint fixes: fine-tuning from it keeps them."""

CHECKPOINT_FORMAT = "newton_lab.policies.diffusion"
CHECKPOINT_VERSION = 1


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
    PickCube it succeeds after 3k steps where epsilon needs about 10k, see the README)."""
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
    compile: bool = False
    """The eager step (CPU, or CUDA with cuda_graph off) runs the network through ``torch.compile``: about a minute
    of compiling on 2 CPU cores, then each step takes ~0.55x the time (the quarter-width U-Net on CPU is bound
    by per-op overhead, which the compiled kernels fuse away). Weights, checkpoints and RNG draws are unchanged."""
    num_workers: int = 0
    """DataLoader worker processes (data is in memory: 0 is usually fastest)."""
    seed: int = 0
    """Seed for weight init, batch order and diffusion noise."""
    device: str = "cpu"
    """Torch device for training ("cpu", "cuda", "cuda:1", ...)."""
    obs_keys: tuple[str, ...] | None = None
    """obs/<term> arrays to condition on; None = every low-dim term except ``actions``."""
    success_only: bool = True
    """Train only on demos marked successful."""
    output_dir: str = "outputs/policies/diffusion"
    """Where train() writes checkpoint.pt and train_log.json."""
    progress: bool = True
    """Show a tqdm progress bar while training."""
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
        self.output_dir = str(self.output_dir)
        levels = len(self.down_dims)
        checks = [
            (self.obs_horizon >= 1, f"obs_horizon must be >= 1, got {self.obs_horizon}"),
            (1 <= self.action_horizon <= self.pred_horizon - self.obs_horizon + 1,
             f"action_horizon must be in 1..pred_horizon - obs_horizon + 1 = "
             f"{self.pred_horizon - self.obs_horizon + 1}, got {self.action_horizon}"),
            (levels >= 1 and all(d > 0 and d % self.n_groups == 0 for d in self.down_dims),
             f"down_dims must be positive multiples of n_groups={self.n_groups}, got {self.down_dims}"),
            (self.pred_horizon % 2 ** (levels - 1) == 0,
             f"pred_horizon must be divisible by 2 ** (len(down_dims) - 1) = {2 ** (levels - 1)}, "
             f"got {self.pred_horizon}"),
            (self.kernel_size % 2 == 1, f"kernel_size must be odd, got {self.kernel_size}"),
            (1 <= self.num_inference_steps <= self.num_train_timesteps,
             f"num_inference_steps must be in 1..num_train_timesteps={self.num_train_timesteps}, "
             f"got {self.num_inference_steps}"),
            (self.activation in ACTIVATIONS,
             f"activation must be one of {', '.join(ACTIVATIONS)}, got {self.activation!r}"),
            (self.prediction_type in PREDICTION_TYPES,
             f"prediction_type must be one of {', '.join(PREDICTION_TYPES)}, got {self.prediction_type!r}"),
            (len(self.betas) == 2, f"betas must be a pair, got {self.betas}"),
            (self.batch_size >= 1 and self.epochs >= 1,
             f"batch_size and epochs must be >= 1, got {self.batch_size} and {self.epochs}"),
            (self.max_steps is None or self.max_steps >= 1, f"max_steps must be None or >= 1, got {self.max_steps}"),
            (self.time_budget_s is None or self.time_budget_s > 0,
             f"time_budget_s must be None or > 0, got {self.time_budget_s}"),
            (self.checkpoint_every_steps is None or self.checkpoint_every_steps >= 1,
             f"checkpoint_every_steps must be None or >= 1, got {self.checkpoint_every_steps}"),
            (self.checkpoint_every_s is None or self.checkpoint_every_s > 0,
             f"checkpoint_every_s must be None or > 0, got {self.checkpoint_every_s}"),
            (self.warmup_steps >= 0 and self.num_workers >= 0,
             f"warmup_steps and num_workers must be >= 0, got {self.warmup_steps} and {self.num_workers}"),
        ]
        for ok, message in checks:
            if not ok:
                raise ValueError(f"DiffusionPolicyConfig: {message}")

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


def _link_new(src: Path, dst: Path) -> None:
    """Publish ``src`` as ``dst`` only if ``dst`` does not exist (atomic where hard links work)."""
    try:
        os.link(src, dst)
    except FileExistsError:
        raise FileExistsError(f"{dst} already exists; pass overwrite=True or choose another path") from None
    except OSError:  # no hard links on this filesystem: exclusive create + copy
        try:
            with open(dst, "xb") as out, open(src, "rb") as inp:
                out.write(inp.read())
        except FileExistsError:
            raise FileExistsError(f"{dst} already exists; pass overwrite=True or choose another path") from None


class DiffusionPolicy(nn.Module):
    """Noise-prediction U-Net + EMA copy + normalisers. Inputs and outputs are in raw (dataset) units.

    ``info`` carries what a deployment needs besides weights: obs_keys, obs_dims, action_joint_names,
    task_id, control_dt, dataset and (after training) ``training`` metadata.
    """

    def __init__(self, cfg: DiffusionPolicyConfig, *, obs_normalizer: MinMaxNormalizer,
                 action_normalizer: MinMaxNormalizer, info: dict[str, Any] | None = None) -> None:
        super().__init__()
        self.cfg = cfg
        self.obs_normalizer, self.action_normalizer = obs_normalizer, action_normalizer
        self.obs_dim, self.action_dim = obs_normalizer.dim, action_normalizer.dim
        self.info: dict[str, Any] = dict(info or {})
        self.model = ConditionalUnet1D(self.action_dim, self.obs_dim * cfg.obs_horizon, down_dims=cfg.down_dims,
                                       diffusion_step_embed_dim=cfg.diffusion_step_embed_dim,
                                       kernel_size=cfg.kernel_size, n_groups=cfg.n_groups,
                                       activation=cfg.activation)
        self.ema = EMA(self.model, power=cfg.ema_power)
        self.scheduler = NoiseScheduler(cfg.num_train_timesteps, clip_sample=True)

    @property
    def train_net(self) -> nn.Module:
        """The network ``compute_loss`` calls: the U-Net, or its ``torch.compile`` wrapper (same parameters)."""
        compiled = self.__dict__.get("_compiled_net")
        return self.model if compiled is None else compiled

    def compile_for_training(self) -> None:
        """Route ``compute_loss`` through ``torch.compile(self.model)`` (kept out of the module tree: the state
        dict, EMA and checkpoints see only ``self.model``)."""
        self.__dict__["_compiled_net"] = torch.compile(self.model)

    @classmethod
    def from_dataset(cls, dataset, cfg: DiffusionPolicyConfig) -> DiffusionPolicy:
        """Fresh policy with normalisers fitted on a ``SequenceDataset``'s frames."""
        meta = dataset.env_args.get("newton_lab", {})
        control_dt = meta["sim_dt"] * meta["decimation"] if "sim_dt" in meta and "decimation" in meta else None
        info = {"task_id": dataset.task_id, "obs_keys": list(dataset.obs_keys), "obs_dims": dict(dataset.obs_dims),
                "action_joint_names": list(dataset.action_joint_names), "control_dt": control_dt,
                "dataset": dataset.source}
        return cls(cfg, obs_normalizer=MinMaxNormalizer.fit(dataset.obs),
                   action_normalizer=MinMaxNormalizer.fit(dataset.actions), info=info)

    @property
    def device(self) -> torch.device:
        return next(self.model.parameters()).device

    @property
    def obs_keys(self) -> list[str]:
        return list(self.info.get("obs_keys", []))

    @property
    def action_joint_names(self) -> list[str]:
        return list(self.info.get("action_joint_names", []))

    @property
    def task_id(self) -> str | None:
        return self.info.get("task_id")

    def compute_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """MSE of the predicted noise (or clean actions, ``prediction_type="sample"``) on a batch
        {"obs": (B, To, Do), "actions": (B, Tp, A)} in raw units."""
        obs = batch["obs"].to(self.device, torch.float32)
        x0 = self.action_normalizer.normalize(batch["actions"].to(self.device, torch.float32))
        cond = self.obs_normalizer.normalize(obs).flatten(1)
        noise = torch.randn_like(x0)
        t = self.scheduler.sample_timesteps(x0.shape[0], device=x0.device)
        target = x0 if self.cfg.prediction_type == "sample" else noise
        return F.mse_loss(self.train_net(self.scheduler.add_noise(x0, noise, t), t, cond), target)

    @torch.no_grad()
    def predict_action(self, obs_history: torch.Tensor, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """(B, obs_horizon, obs_dim) raw obs -> (B, action_horizon, action_dim) raw actions (EMA weights, DDIM).

        Returned steps are obs_horizon-1 .. obs_horizon-1+action_horizon-1 of the predicted sequence, i.e.
        the action for the newest observation first. ``generator`` makes the initial noise reproducible.
        """
        cfg = self.cfg
        obs = torch.as_tensor(obs_history)
        out_device = obs.device
        obs = obs.to(self.device, torch.float32)
        if obs.ndim != 3 or tuple(obs.shape[1:]) != (cfg.obs_horizon, self.obs_dim):
            raise ValueError(f"obs_history must be (B, {cfg.obs_horizon}, {self.obs_dim}) "
                             f"(obs_keys {self.obs_keys}), got {tuple(obs.shape)}")
        cond = self.obs_normalizer.normalize(obs).flatten(1)
        shape = (obs.shape[0], cfg.pred_horizon, self.action_dim)
        noise_device = generator.device if generator is not None else self.device
        x_T = torch.randn(shape, generator=generator, device=noise_device).to(self.device)
        net = self.ema.averaged.eval()
        x0 = self.scheduler.sample(lambda x, t: net(x, t, cond), x_T, num_inference_steps=cfg.num_inference_steps,
                                   prediction_type=cfg.prediction_type)
        start = cfg.obs_horizon - 1
        return self.action_normalizer.unnormalize(x0[:, start:start + cfg.action_horizon]).to(out_device)

    # ------------------------------------------------------------------------- checkpoints
    def checkpoint(self) -> dict[str, Any]:
        """The checkpoint payload: EMA weights, normaliser stats, config and ``info`` (all weights_only-loadable)."""
        return {"format": CHECKPOINT_FORMAT, "version": CHECKPOINT_VERSION, "backend": "diffusion",
                "config": self.cfg.to_dict(),
                "weights": {k: v.detach().cpu() for k, v in self.ema.averaged.state_dict().items()},
                "normalizers": {"obs": self.obs_normalizer.state_dict(), "action": self.action_normalizer.state_dict()},
                "info": self.info}

    def save(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Write the checkpoint atomically; an existing file raises FileExistsError unless ``overwrite``."""
        path = Path(path)
        if not overwrite and path.exists():
            raise FileExistsError(f"{path} already exists; pass overwrite=True or choose another path")
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            torch.save(self.checkpoint(), tmp)
            if overwrite:
                os.replace(tmp, path)
            else:
                _link_new(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
        return path

    @classmethod
    def load(cls, path: str | Path, *, device: str | torch.device = "cpu") -> DiffusionPolicy:
        """Rebuild a policy from ``save``'s file (EMA weights go into both the model and its EMA copy)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"policy checkpoint {path} does not exist or is not a file; check the path")

        def damaged(reason: object) -> ValueError:
            reason = " ".join(str(reason).split())[:160]
            return ValueError(f"{path} is not a newton_lab diffusion-policy checkpoint or is damaged ({reason})")

        try:
            with warnings.catch_warnings():  # torch warns about odd pickle protocols before failing
                warnings.simplefilter("ignore")
                ckpt = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:  # noqa: BLE001 - any unpickling failure means a bad file
            raise damaged(f"{type(exc).__name__}: {exc}") from None
        if not isinstance(ckpt, dict) or ckpt.get("format") != CHECKPOINT_FORMAT:
            raise damaged("missing or unknown 'format' tag")
        if not isinstance(ckpt.get("version"), int) or ckpt["version"] > CHECKPOINT_VERSION:
            raise damaged(f"checkpoint version {ckpt.get('version')!r} is not supported "
                          f"(this newton_lab reads <= {CHECKPOINT_VERSION})")
        try:
            cfg = DiffusionPolicyConfig.from_dict(ckpt["config"])
            policy = cls(cfg, obs_normalizer=MinMaxNormalizer.from_state_dict(ckpt["normalizers"]["obs"]),
                         action_normalizer=MinMaxNormalizer.from_state_dict(ckpt["normalizers"]["action"]),
                         info=ckpt["info"])
            policy.model.load_state_dict(ckpt["weights"])
            policy.ema.averaged.load_state_dict(ckpt["weights"])
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            raise damaged(f"{type(exc).__name__}: {exc}") from None
        return policy.to(device)

    def __repr__(self) -> str:
        n = sum(p.numel() for p in self.model.parameters())
        return (f"DiffusionPolicy(task={self.task_id!r}, obs_dim={self.obs_dim}, action_dim={self.action_dim}, "
                f"horizons={self.cfg.obs_horizon}/{self.cfg.action_horizon}/{self.cfg.pred_horizon}, params={n:,})")
