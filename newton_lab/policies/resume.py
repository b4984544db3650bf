"""The resume file of an unfinished training run: ``<output_dir>/resume.pt``, replaced atomically.

It holds everything the next optimiser step depends on: raw and EMA weights, AdamW state, the LR schedule's
plan (total steps, time-budget rate), every RNG state (torch CPU and CUDA, numpy, python), the step count, the
epoch log and the data order (the batch-order generator at the start of the running epoch and the steps taken
in it). ``train(..., resume=True)`` continues from it exactly: on the CPU the final weights are bitwise those of
an uninterrupted run. It is written to a temporary file, fsynced and moved over the old one with
``os.replace`` (a kill leaves the previous resume file or none, never half of one), and deleted once the final
checkpoint is written. Loaded with ``weights_only=True``.
"""

from __future__ import annotations

import hashlib
import os
import random
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ..datasets.files.output_paths import output_path
from .diffusion import ARCHITECTURE_FIELDS, DiffusionPolicy, DiffusionPolicyConfig, save_file
from .normalize import MinMaxNormalizer

RESUME_NAME = "resume.pt"
RESUME_FORMAT = "newton_lab.policies.resume"
RESUME_VERSION = 1
RESUME_KEYS = ("config", "policy", "optimizer", "data_order", "data", "progress", "rng")
FREE_ON_RESUME = (
    "progress",
    "time_budget_s",
    "checkpoint_every_steps",
    "checkpoint_every_s",
    "num_workers",
    "output_dir",
    "device",
    "cuda_graph",
)
"""Config fields a resumed run may change; the others must be the interrupted run's (they shape its steps)."""


def resume_path(out_dir: str | Path) -> Path:
    return Path(out_dir).expanduser() / RESUME_NAME


def capture_rng() -> dict[str, Any]:
    """Every RNG state a training step may read: torch CPU, torch CUDA (when initialised), numpy, python."""
    np_state = np.random.get_state(legacy=False)
    return {
        "torch": torch.get_rng_state(),
        "cuda": torch.cuda.get_rng_state_all() if torch.cuda.is_available() and torch.cuda.is_initialized() else [],
        "numpy": {
            **np_state,
            "state": {
                "key": torch.from_numpy(np_state["state"]["key"].astype(np.int64)),
                "pos": int(np_state["state"]["pos"]),
            },
        },
        "python": random.getstate(),
    }


def restore_rng(state: dict[str, Any]) -> None:
    torch.set_rng_state(state["torch"])
    if state["cuda"] and torch.cuda.is_available() and len(state["cuda"]) == torch.cuda.device_count():
        torch.cuda.set_rng_state_all(state["cuda"])
    np_state = state["numpy"]
    np.random.set_state(
        {
            **np_state,
            "state": {"key": np_state["state"]["key"].numpy().astype(np.uint32), "pos": np_state["state"]["pos"]},
        }
    )
    version, internal, gauss = state["python"]
    random.setstate((version, tuple(internal), gauss))


def data_fingerprint(data) -> str:
    """Digest of a ``SequenceDataset``'s frames and windows: a resumed run must draw from the same data."""
    digest = hashlib.blake2b(digest_size=16)
    for tensor in (data.obs, data.actions, data.obs_index, data.action_index):
        digest.update(tensor.contiguous().numpy())  # the buffer itself: no copy
    return digest.hexdigest()


def write_atomic(payload: dict[str, Any], path: Path) -> None:
    """``torch.save`` to a temporary file beside ``path``, fsync, then ``os.replace`` (and fsync the folder)."""
    output_path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            save_file(payload, f, path)  # a full disk: one line
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    try:
        folder = os.open(path.parent, os.O_RDONLY)
    except OSError:  # a folder that cannot be opened (some platforms): the rename is still atomic
        return
    try:
        os.fsync(folder)
    finally:
        os.close(folder)


def remove_stale_temps(out_dir: Path) -> None:
    """Delete temporary resume files of killed writers (a live process's own is left alone)."""
    for tmp in out_dir.glob(f".{RESUME_NAME}.*.tmp"):
        try:
            os.kill(int(tmp.name.split(".")[-2]), 0)
        except ValueError:
            continue
        except ProcessLookupError:
            tmp.unlink(missing_ok=True)
        except PermissionError:  # alive, another user's
            continue


def refuse_fresh_run(out_dir: Path) -> None:
    """A fresh run must not overwrite an interrupted one's resume file."""
    if resume_path(out_dir).exists():
        raise FileExistsError(
            f"{resume_path(out_dir)} holds an interrupted run; continue it with --resume "
            "(resume=True) or delete that file to start over"
        )


def load_resume(out_dir: Path) -> dict[str, Any]:
    """The resume file of ``out_dir``, or a one-line error naming the fix."""
    path = resume_path(out_dir)
    if not path.is_file():
        raise FileNotFoundError(
            f"no resume file {path}: nothing to resume there; check --output-dir, "
            "or train without --resume to start from step 0"
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unpickling failure means a bad file
        state = " ".join(f"{type(exc).__name__}: {exc}".split())[:120]
    if (
        not isinstance(state, dict)
        or state.get("format") != RESUME_FORMAT
        or state.get("version") != RESUME_VERSION
        or not all(k in state for k in RESUME_KEYS)
    ):
        reason = state if isinstance(state, str) else "not a complete newton_lab resume file of this version"
        raise ValueError(f"{path} is damaged ({reason}); delete it and train without --resume to start from step 0")
    return state


def check_resumable(state: dict[str, Any], cfg: DiffusionPolicyConfig, data, out_dir: Path) -> None:
    """One-line error unless ``cfg`` and ``data`` are the interrupted run's (``FREE_ON_RESUME`` may differ)."""
    saved, now = state["config"], cfg.to_dict()
    diff = [f"{k}={saved.get(k)!r} (now {now[k]!r})" for k in now if k not in FREE_ON_RESUME and saved.get(k) != now[k]]
    if state["data"]["fingerprint"] != data_fingerprint(data):
        diff.append(f"the dataset ({state['data']['source']})")
    if diff:
        raise ValueError(
            f"{resume_path(out_dir)} was written by a run with other settings: {', '.join(diff)}; "
            "resume with the same dataset and settings, or delete it to start over"
        )


def resumed_config(state: dict[str, Any], cfg: DiffusionPolicyConfig) -> DiffusionPolicyConfig:
    """``cfg`` with the interrupted run's architecture when it was fine-tuned (the init checkpoint fixed it)."""
    if cfg.init_checkpoint is None:
        return cfg
    return cfg.with_architecture_of(
        DiffusionPolicyConfig.from_dict({k: v for k, v in state["config"].items() if k in ARCHITECTURE_FIELDS})
    )


def policy_state(policy: DiffusionPolicy) -> dict[str, Any]:
    return {
        "normalizers": {"obs": policy.obs_normalizer.state_dict(), "action": policy.action_normalizer.state_dict()},
        "info": policy.info,
        "model": policy.model.state_dict(),
        "ema": policy.ema.averaged.state_dict(),
        "ema_updates": policy.ema.num_updates,
    }


def restore_policy(state: dict[str, Any], cfg: DiffusionPolicyConfig) -> DiffusionPolicy:
    """The interrupted run's policy (raw and EMA weights, normalisers, info) on ``cfg.device``."""
    saved = state["policy"]
    policy = DiffusionPolicy(
        cfg,
        obs_normalizer=MinMaxNormalizer.from_state_dict(saved["normalizers"]["obs"]),
        action_normalizer=MinMaxNormalizer.from_state_dict(saved["normalizers"]["action"]),
        info=saved["info"],
    )
    policy.model.load_state_dict(saved["model"])
    policy.ema.averaged.load_state_dict(saved["ema"])
    policy.ema.num_updates = saved["ema_updates"]
    return policy.to(cfg.device)
