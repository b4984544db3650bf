"""Training loop: AdamW, linear warm-up + cosine LR, EMA every step, tqdm, checkpoint + JSON log.

Existing checkpoints are never replaced: when ``<output_dir>/checkpoint.pt`` exists, the run is written
to the first free ``checkpoint-<k>.pt`` (with a matching ``train_log-<k>.json``) and a warning names it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
from tqdm import tqdm

from .data import SequenceDataset
from .diffusion import DiffusionPolicy, DiffusionPolicyConfig
from .train_step import CudaGraphTrainStep, make_train_step, set_lr, steps_per_epoch


def as_config(cfg: DiffusionPolicyConfig | dict[str, Any] | None) -> DiffusionPolicyConfig:
    """Accept a config, a plain dict of its fields, or None (defaults)."""
    if cfg is None:
        return DiffusionPolicyConfig()
    if isinstance(cfg, DiffusionPolicyConfig):
        return cfg
    if isinstance(cfg, dict):
        return DiffusionPolicyConfig.from_dict(cfg)
    raise TypeError(f"train config must be a DiffusionPolicyConfig or dict, got {type(cfg).__name__}")


def warmup_cosine(warmup_steps: int, total_steps: int | Callable[[], int]) -> Callable[[int], float]:
    """LR factor for step s (0-based): linear to 1 over ``warmup_steps``, then cosine to 0 at ``total_steps``
    (an int, or a callable read at every step, for a run re-planned to a time budget)."""

    def factor(step: int) -> float:
        if step < warmup_steps:
            return (step + 1) / warmup_steps
        total = total_steps() if callable(total_steps) else total_steps
        progress = min(1.0, (step - warmup_steps) / max(1, total - warmup_steps))
        return 0.5 * (1.0 + math.cos(math.pi * progress))

    return factor


def _free_names(out_dir: Path) -> tuple[Path, Path]:
    """First (checkpoint, log) pair of ``checkpoint[-k].pt`` / ``train_log[-k].json`` where neither exists."""
    k = 0
    while True:
        suffix = f"-{k}" if k else ""
        ckpt, log = out_dir / f"checkpoint{suffix}.pt", out_dir / f"train_log{suffix}.json"
        if not ckpt.exists() and not log.exists():
            return ckpt, log
        k += 1


def _save_run(policy: DiffusionPolicy, out_dir: Path, log: dict[str, Any]) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    while True:
        ckpt_path, log_path = _free_names(out_dir)
        try:
            policy.save(ckpt_path)  # exclusive: raises if another process took the name meanwhile
            break
        except FileExistsError:
            continue
    tmp = log_path.with_name(f".{log_path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps({**log, "checkpoint": str(ckpt_path)}, indent=2) + "\n")
    os.replace(tmp, log_path)
    if ckpt_path.name != "checkpoint.pt":
        warnings.warn(f"{out_dir / 'checkpoint.pt'} already exists; this run was saved as {ckpt_path}", stacklevel=3)
    return ckpt_path


def _fit_to_budget(step: int, elapsed: float, budget: float, cap: int, rate_from: tuple[int, float],
                   total: int) -> int:
    """Planned total steps so the loop ends within ``budget`` seconds: re-planned at step 50 (rate over the
    first 50 steps), then every 100 steps from the rate since step 50 (the machine may speed up or slow
    down; each re-plan moves the cosine schedule only a little); never above ``cap``."""
    start, t_start = rate_from
    if step == start:
        rate = step / elapsed
    elif step > start and step % 100 == 0:
        rate = (step - start) / max(elapsed - t_start, 1e-9)
    else:
        return total
    return min(cap, step + max(0, int((budget - elapsed) * rate * 0.97)))  # == step: stop now


def _continue(policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig) -> DiffusionPolicy:
    """``policy`` (loaded from ``cfg.init_checkpoint``) ready to train on ``data``: same task, observation
    layout and actions, or a one-line error. Its normalisers stay (the weights were trained against them)."""
    info = policy.info
    problems = []
    if info.get("task_id") not in (None, data.task_id):
        problems.append(f"it was trained for {info['task_id']}, the dataset is {data.task_id}")
    if dict(info.get("obs_dims", {})) != dict(data.obs_dims):
        problems.append(f"observation sizes {info.get('obs_dims')} differ from the dataset's {data.obs_dims}")
    if list(info.get("action_joint_names", [])) != list(data.action_joint_names):
        problems.append("its action columns differ from the dataset's")
    if problems:
        raise ValueError(f"cannot continue from {cfg.init_checkpoint}: {'; '.join(problems)}; "
                         "train from scratch (no init_checkpoint) or pick a matching dataset")
    policy.cfg = cfg
    policy.info["dataset"] = data.source
    policy.model.train()
    return policy


def train(dataset: str | Path | Any, cfg: DiffusionPolicyConfig | dict[str, Any] | None = None) -> Path:
    """Train a diffusion policy on a dataset (a path, an object with ``.path``, or a list of them: same task and
    action columns, trained as one); returns the checkpoint path."""
    cfg = as_config(cfg)
    many = isinstance(dataset, (list, tuple))
    paths = [Path(getattr(d, "path", d)).expanduser() for d in (dataset if many else [dataset])]
    for path in paths:
        if not path.exists():
            raise FileNotFoundError(f"dataset {path} does not exist; check the path")
    torch.manual_seed(cfg.seed)
    start = None
    if cfg.init_checkpoint is not None:
        start = DiffusionPolicy.load(cfg.init_checkpoint, device=cfg.device)
        cfg = cfg.with_architecture_of(dataclasses.replace(start.cfg, obs_keys=tuple(start.obs_keys)))
    data = SequenceDataset(paths, obs_keys=cfg.obs_keys, obs_horizon=cfg.obs_horizon,
                           pred_horizon=cfg.pred_horizon, success_only=cfg.success_only)
    policy = DiffusionPolicy.from_dataset(data, cfg).to(cfg.device) if start is None else _continue(start, data, cfg)
    stepper = make_train_step(policy, data, cfg)
    per_epoch = steps_per_epoch(data, cfg.batch_size)
    total = per_epoch * cfg.epochs if cfg.max_steps is None else min(per_epoch * cfg.epochs, cfg.max_steps)
    lr_factor = warmup_cosine(cfg.warmup_steps, lambda: total)
    cap = total
    rate_from = (50, 0.0)  # (step, time): the rate is measured after the first 50 steps (warm-up, autotuning)

    epochs: list[dict[str, Any]] = []
    step, t0 = 0, time.perf_counter()
    policy.model.train()
    set_lr(stepper.optimizer, cfg.lr * lr_factor(0))
    with tqdm(total=total, desc=f"diffusion policy {data.task_id}", unit="step", disable=not cfg.progress) as bar:
        while step < total:
            losses = []
            for loss in stepper.epoch():
                losses.append(loss)  # no host sync per step: read back every 50 steps
                step += 1
                bar.update()
                if cfg.time_budget_s is not None:
                    elapsed = time.perf_counter() - t0
                    total = _fit_to_budget(step, elapsed, cfg.time_budget_s, cap, rate_from, total)
                    if step == rate_from[0]:
                        rate_from = (step, elapsed)
                    bar.total = total
                if step % 50 == 0:
                    bar.set_postfix(loss=f"{losses[-1].item():.4f}", epoch=len(epochs) + 1, refresh=False)
                if step >= total:
                    break
                set_lr(stepper.optimizer, cfg.lr * lr_factor(step))
            epochs.append({"epoch": len(epochs) + 1, "loss": torch.stack(losses).mean().item(), "steps": step,
                           "lr": cfg.lr * lr_factor(step)})
    wall = time.perf_counter() - t0

    training = {"final_loss": epochs[-1]["loss"], "epochs": len(epochs), "steps": step, "wall_time_s": round(wall, 3),
                "init_checkpoint": cfg.init_checkpoint, "num_demos": len(data.demos), "num_windows": len(data),
                "batch_size": cfg.batch_size, "cuda_graph": isinstance(stepper, CudaGraphTrainStep),
                "parameters": sum(p.numel() for p in policy.model.parameters()),
                "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    policy.info["training"] = training
    log = {"task_id": data.task_id, "dataset": data.source, **training, "config": cfg.to_dict(),
           "epoch_log": epochs}
    return _save_run(policy, Path(cfg.output_dir).expanduser(), log)
