"""Diffusion Policy (Chi et al. 2023, CNN variant) on low-dim observations and, with ``image_keys``, camera frames
(``vision.ImageEncoder``): the model wrapper and its checkpoints (settings: ``config``)."""

from __future__ import annotations

import errno
import os
import shutil
import warnings
from pathlib import Path
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from ..datasets.files.errors import STORAGE_ERRNOS, DatasetWriteError
from ..datasets.files.output_paths import output_path
from .config import ARCHITECTURE_FIELDS, PRESETS, DiffusionPolicyConfig  # noqa: F401  (re-exported)
from .data_parallel import draw_rows
from .ema import EMA
from .model import ConditionalUnet1D
from .norm import set_low_precision_norms
from .normalize import MinMaxNormalizer
from .scheduler import NoiseScheduler
from .vision import ImageEncoder

CHECKPOINT_FORMAT = "newton_lab.policies.diffusion"
CHECKPOINT_VERSION = 1
FULL_BELOW_BYTES = 1 << 20
"""Free bytes under which a failed ``torch.save`` (torch reports a short write as a RuntimeError) is a full disk."""
SHORT_WRITE = ("unexpected pos", "file write failed", "PytorchStreamWriter failed")
"""How torch's RuntimeError says a write came up short (the disk, a quota or a file size limit refused it)."""


class VisuomotorNet(nn.Module):
    """The U-Net and the image encoder as one module: one optimiser, one EMA copy, one state dict."""

    def __init__(self, unet: ConditionalUnet1D, encoder: ImageEncoder) -> None:
        super().__init__()
        self.unet, self.encoder = unet, encoder

    def forward(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        return self.unet(x, t, cond)


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


def save_file(payload: dict[str, Any], file: Any, path: Path) -> None:
    """``torch.save(payload, file)`` (a path, or an open file, and its flush), for ``path``: a write the disk refuses
    (full, or failing) is one line (``DatasetWriteError``: exit status 1 on the command line) instead of torch's
    RuntimeError; the caller removes the temporary file."""
    try:
        torch.save(payload, file)
        if hasattr(file, "flush"):
            file.flush()
            os.fsync(file.fileno())
    except (RuntimeError, OSError) as exc:
        code = getattr(exc, "errno", None)
        short = isinstance(exc, RuntimeError) and any(w in str(exc) for w in SHORT_WRITE)
        if code in STORAGE_ERRNOS or short:
            full = code == errno.ENOSPC or (code is None and shutil.disk_usage(path.parent).free < FULL_BELOW_BYTES)
            what = "disk full" if full else f"the disk refused a write ({os.strerror(code) if code else 'short write'})"
            raise DatasetWriteError(
                f"{what} while writing {path}; free space and run again (a training run that "
                "wrote a resume point goes on from it with --resume)",
                code or errno.ENOSPC,
            ) from None
        raise


class DiffusionPolicy(nn.Module):
    """Noise-prediction U-Net + EMA copy + normalisers. Inputs and outputs are in raw (dataset) units.

    ``info`` carries what a deployment needs besides weights: obs_keys, obs_dims, action_joint_names,
    task_id, control_dt, dataset and (after training) ``training`` metadata.
    """

    def __init__(
        self,
        cfg: DiffusionPolicyConfig,
        *,
        obs_normalizer: MinMaxNormalizer,
        action_normalizer: MinMaxNormalizer,
        info: dict[str, Any] | None = None,
    ) -> None:
        super().__init__()
        self.cfg = cfg
        self.obs_normalizer, self.action_normalizer = obs_normalizer, action_normalizer
        self.obs_dim, self.action_dim = obs_normalizer.dim, action_normalizer.dim
        self.info: dict[str, Any] = dict(info or {})
        encoder = None
        self.instruction_spans = self._instruction_spans()
        if cfg.image_keys:
            shapes = self.info.get("image_shapes") or {}
            missing = [k for k in cfg.image_keys if k not in shapes]
            if missing:
                raise ValueError(f"image_shapes (H, W, C) of {missing} are needed to build the image encoder")
            encoder = ImageEncoder(
                {k: shapes[k] for k in cfg.image_keys},
                crop=cfg.crop,
                feature_dim=cfg.image_feature_dim,
                width=cfg.encoder_width,
                instruction_dim=sum(b - a for a, b in self.instruction_spans),
            )
        cond_dim = (self.obs_dim + (encoder.feature_dim if encoder else 0)) * cfg.obs_horizon
        unet = ConditionalUnet1D(
            self.action_dim,
            cond_dim,
            down_dims=cfg.down_dims,
            diffusion_step_embed_dim=cfg.diffusion_step_embed_dim,
            kernel_size=cfg.kernel_size,
            n_groups=cfg.n_groups,
            activation=cfg.activation,
        )
        self.model = unet if encoder is None else VisuomotorNet(unet, encoder)
        set_low_precision_norms(self.model, cfg.bf16_norms)  # before the EMA copy: its norms follow the model's
        self.ema = EMA(self.model, power=cfg.ema_power)
        self.scheduler = NoiseScheduler(cfg.num_train_timesteps, clip_sample=True)

    def _instruction_spans(self) -> list[tuple[int, int]]:
        """(start, stop) columns of the obs vector (``info`` obs_keys / obs_dims order) of each of
        ``cfg.instruction_keys`` (slices, not an index list: a CUDA graph captures them without a host copy)."""
        keys = list(self.info.get("obs_keys", []))
        dims = self.info.get("obs_dims", {})
        missing = [k for k in self.cfg.instruction_keys or () if k not in keys]
        if missing:
            raise ValueError(f"instruction_keys {missing} are not observed; the policy sees obs_keys {keys}")
        spans, start = [], 0
        for k in keys:
            width = int(dims.get(k, 0))
            if k in (self.cfg.instruction_keys or ()):
                spans.append((start, start + width))
            start += width
        return spans

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
        info = {
            "task_id": dataset.task_id,
            "obs_keys": list(dataset.obs_keys),
            "obs_dims": dict(dataset.obs_dims),
            "action_joint_names": list(dataset.action_joint_names),
            "control_dt": control_dt,
            "dataset": dataset.source,
        }
        if cfg.image_keys:
            info.update(
                image_keys=list(cfg.image_keys),
                image_shapes={k: list(v) for k, v in getattr(dataset, "image_shapes", {}).items()},
            )
        return cls(
            cfg,
            obs_normalizer=MinMaxNormalizer.fit(dataset.obs, min_range=cfg.obs_min_range),
            action_normalizer=MinMaxNormalizer.fit(dataset.actions),
            info=info,
        )

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

    @property
    def image_keys(self) -> list[str]:
        return list(self.cfg.image_keys or ())

    def condition(self, obs: torch.Tensor, images, net: nn.Module) -> torch.Tensor:
        """The U-Net's global condition: normalised obs (B, To, Do), plus ``net``'s image features, flattened."""
        cond = self.obs_normalizer.normalize(obs)
        if self.cfg.image_keys:
            if images is None:
                raise ValueError(
                    f"this policy sees images {self.image_keys}; pass images={{key: (B, "
                    f"{self.cfg.obs_horizon}, H, W, 3) uint8}}"
                )
            net.encoder.check(images)
            spans = self.instruction_spans
            instruction = torch.cat([cond[..., a:b] for a, b in spans], dim=-1) if spans else None
            cond = torch.cat([cond, net.encoder(images, instruction)], dim=-1)
        return cond.flatten(1)

    def compute_loss(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """MSE of the predicted noise (or clean actions, ``prediction_type="sample"``) on a batch
        {"obs": (B, To, Do), "actions": (B, Tp, A)[, "images": {key: (B, To, H, W, 3)}]} in raw units."""
        obs = batch["obs"].to(self.device, torch.float32)
        x0 = self.action_normalizer.normalize(batch["actions"].to(self.device, torch.float32))
        rows, shape = x0.shape[0], x0.shape[1:]  # data-parallel: drawn for the global batch, this rank's rows kept
        noise = draw_rows(lambda n: torch.randn((n, *shape), device=x0.device, dtype=x0.dtype), rows)
        t = draw_rows(lambda n: self.scheduler.sample_timesteps(n, device=x0.device), rows)
        target = x0 if self.cfg.prediction_type == "sample" else noise
        with torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=self.cfg.bf16):
            cond = self.condition(obs, batch.get("images"), self.model)
            pred = self.train_net(self.scheduler.add_noise(x0, noise, t), t, cond)
        return F.mse_loss(pred.float(), target)

    @torch.no_grad()
    def predict_action(
        self, obs_history: torch.Tensor, *, images=None, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """(B, obs_horizon, obs_dim) raw obs [and ``images`` {key: (B, obs_horizon, H, W, 3) uint8}] -> (B,
        action_horizon, action_dim) raw actions (EMA weights, DDIM).

        Returned steps are obs_horizon-1 .. obs_horizon-1+action_horizon-1 of the predicted sequence, i.e.
        the action for the newest observation first. ``generator`` makes the initial noise reproducible.
        """
        obs = torch.as_tensor(obs_history)
        if obs.ndim != 3 or tuple(obs.shape[1:]) != (self.cfg.obs_horizon, self.obs_dim):
            raise ValueError(
                f"obs_history must be (B, {self.cfg.obs_horizon}, {self.obs_dim}) "
                f"(obs_keys {self.obs_keys}), got {tuple(obs.shape)}"
            )
        return self.sample_actions(obs, images, self.initial_noise(obs.shape[0], generator)).to(obs.device)

    def initial_noise(self, batch: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """x_T of ``batch`` samples, N(0, I) (B, pred_horizon, action_dim), drawn on ``generator``'s device and
        moved to the policy's."""
        noise_device = generator.device if generator is not None else self.device
        shape = (batch, self.cfg.pred_horizon, self.action_dim)
        return torch.randn(shape, generator=generator, device=noise_device).to(self.device)

    @torch.no_grad()
    def sample_actions(self, obs: torch.Tensor, images, x_T: torch.Tensor) -> torch.Tensor:
        """The device work of ``predict_action`` from its initial noise ``x_T``: condition, DDIM, unnormalise ->
        (B, action_horizon, action_dim) on the policy's device. No host round trip, so a CUDA graph can capture it
        (``policies.graphed.GraphedSampler``)."""
        cfg = self.cfg
        net = self.ema.averaged.eval()
        cond = self.condition(obs.to(self.device, torch.float32), images, net)
        x0 = self.scheduler.sample(
            lambda x, t: net(x, t, cond),
            x_T,
            num_inference_steps=cfg.num_inference_steps,
            prediction_type=cfg.prediction_type,
        )
        start = cfg.obs_horizon - 1
        return self.action_normalizer.unnormalize(x0[:, start : start + cfg.action_horizon])

    # ------------------------------------------------------------------------- checkpoints
    def checkpoint(self) -> dict[str, Any]:
        """The checkpoint payload: EMA weights, normaliser stats, config and ``info`` (all weights_only-loadable)."""
        return {
            "format": CHECKPOINT_FORMAT,
            "version": CHECKPOINT_VERSION,
            "backend": "diffusion",
            "config": self.cfg.to_dict(),
            "weights": {k: v.detach().cpu() for k, v in self.ema.averaged.state_dict().items()},
            "normalizers": {"obs": self.obs_normalizer.state_dict(), "action": self.action_normalizer.state_dict()},
            "info": self.info,
        }

    def save(self, path: str | Path, *, overwrite: bool = False) -> Path:
        """Write the checkpoint atomically; an existing file raises FileExistsError unless ``overwrite``."""
        path = Path(path)
        if not overwrite and path.exists():
            raise FileExistsError(f"{path} already exists; pass overwrite=True or choose another path")
        output_path(path)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            save_file(self.checkpoint(), tmp, path)
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
            raise damaged(
                f"checkpoint version {ckpt.get('version')!r} is not supported "
                f"(this newton_lab reads <= {CHECKPOINT_VERSION})"
            )
        try:
            cfg = DiffusionPolicyConfig.from_dict(ckpt["config"])
            policy = cls(
                cfg,
                obs_normalizer=MinMaxNormalizer.from_state_dict(ckpt["normalizers"]["obs"]),
                action_normalizer=MinMaxNormalizer.from_state_dict(ckpt["normalizers"]["action"]),
                info=ckpt["info"],
            )
            policy.model.load_state_dict(ckpt["weights"])
            policy.ema.averaged.load_state_dict(ckpt["weights"])
        except (KeyError, TypeError, ValueError, RuntimeError) as exc:
            raise damaged(f"{type(exc).__name__}: {exc}") from None
        return policy.to(device)

    def __repr__(self) -> str:
        n = sum(p.numel() for p in self.model.parameters())
        return (
            f"DiffusionPolicy(task={self.task_id!r}, obs_dim={self.obs_dim}, action_dim={self.action_dim}, "
            f"horizons={self.cfg.obs_horizon}/{self.cfg.action_horizon}/{self.cfg.pred_horizon}, params={n:,})"
        )
