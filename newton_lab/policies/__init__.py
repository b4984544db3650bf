"""Imitation-learning policies trained on newton_lab demonstration datasets.

    backend = Policy.from_backend("diffusion")
    ckpt = backend.train("demos.hdf5", {"epochs": 50, "output_dir": "outputs/dp"})
    policy = backend.load_policy(ckpt)
    actions = policy.predict_action(obs_history)  # (B, obs_horizon, obs_dim) -> (B, action_horizon, A)

``PolicyAgent`` (``newton_lab.policies.agent``) runs a checkpoint on an env; it is not imported here, so
training needs neither Warp nor Newton.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .data import SequenceDataset
from .diffusion import DiffusionPolicy, DiffusionPolicyConfig
from .normalize import MinMaxNormalizer
from .scheduler import NoiseScheduler
from .train import train

__all__ = [
    "Policy",
    "DiffusionBackend",
    "DiffusionPolicy",
    "DiffusionPolicyConfig",
    "SequenceDataset",
    "MinMaxNormalizer",
    "NoiseScheduler",
    "train",
    "load_policy",
    "BACKENDS",
]


class DiffusionBackend:
    """Diffusion Policy (1-D conv U-Net, DDPM training, DDIM inference) on low-dim observations."""

    name = "diffusion"
    config_class = DiffusionPolicyConfig

    def train(
        self,
        dataset: str | Path | Any,
        train_cfg: dict[str, Any] | DiffusionPolicyConfig | None = None,
        *,
        resume: bool = False,
        gpus: int = 1,
    ) -> Path:
        """Train on ``dataset`` (path or object with ``.path``); returns the written checkpoint path. ``resume``:
        continue the interrupted run of ``output_dir`` from its ``resume.pt``; ``gpus`` > 1: data-parallel."""
        return train(dataset, train_cfg, resume=resume, gpus=gpus)

    def load_policy(self, path: str | Path, *, device: str = "cpu") -> DiffusionPolicy:
        """Load a checkpoint written by ``train`` / ``DiffusionPolicy.save``."""
        return DiffusionPolicy.load(path, device=device)

    def __repr__(self) -> str:
        return "Policy.from_backend('diffusion')"


BACKENDS = {"diffusion": DiffusionBackend}


class Policy:
    """Entry point: ``Policy.from_backend(name)`` returns a backend with ``train`` and ``load_policy``."""

    @staticmethod
    def from_backend(name: str) -> DiffusionBackend:
        try:
            return BACKENDS[name]()
        except (KeyError, TypeError):
            raise ValueError(f"unknown policy backend {name!r}; valid backends: {', '.join(BACKENDS)}") from None


def load_policy(path: str | Path, *, device: str = "cpu") -> DiffusionPolicy:
    """Load any policy checkpoint (today: diffusion) written by a backend's ``train`` or ``save``."""
    return DiffusionBackend().load_policy(path, device=device)
