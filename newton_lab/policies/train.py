"""Training loop: AdamW, linear warm-up + cosine LR, EMA every step, tqdm, checkpoint + JSON log.

Existing checkpoints are never replaced: when ``<output_dir>/checkpoint.pt`` exists, the run is written
to the first free ``checkpoint-<k>.pt`` (with a matching ``train_log-<k>.json``) and a warning names it.
While it runs, ``<output_dir>/resume.pt`` is replaced atomically every ``checkpoint_every_steps`` steps or
``checkpoint_every_s`` seconds (``newton_lab.policies.resume``); ``train(..., resume=True)`` continues from it
and it is deleted once the final checkpoint is written.
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
import warnings
from contextlib import nullcontext
from pathlib import Path
from typing import Any

import torch

from ..datasets import read_dataset_info
from ..datasets.files.output_paths import output_path
from ..datasets.writers.interrupts import stop_requests
from . import data_parallel
from .data import SequenceDataset
from .diffusion import DiffusionPolicy, DiffusionPolicyConfig
from .resume import (
    check_resumable,
    load_resume,
    refuse_fresh_run,
    remove_stale_temps,
    restore_policy,
    restore_rng,
    resumed_config,
)
from .train_loop import Checkpointer, Progress, run_steps
from .train_step import CudaGraphTrainStep, EagerTrainStep, load_optimizer_state, make_train_step, steps_per_epoch


def as_config(cfg: DiffusionPolicyConfig | dict[str, Any] | None) -> DiffusionPolicyConfig:
    """Accept a config, a plain dict of its fields, or None (defaults)."""
    if cfg is None:
        return DiffusionPolicyConfig()
    if isinstance(cfg, DiffusionPolicyConfig):
        return cfg
    if isinstance(cfg, dict):
        return DiffusionPolicyConfig.from_dict(cfg)
    raise TypeError(f"train config must be a DiffusionPolicyConfig or dict, got {type(cfg).__name__}")


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
    output_path(out_dir / "checkpoint.pt")
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
        raise ValueError(
            f"cannot continue from {cfg.init_checkpoint}: {'; '.join(problems)}; "
            "train from scratch (no init_checkpoint) or pick a matching dataset"
        )
    policy.cfg = cfg
    policy.info["dataset"] = data.source
    policy.model.train()
    return policy


def _resume(state: dict[str, Any], policy: DiffusionPolicy, stepper: EagerTrainStep | CudaGraphTrainStep) -> Progress:
    """Optimizer, data order and loop state of the interrupted run; its RNG states are restored when the first
    resumed epoch has rewound its data order (the DataLoader draws from them at an epoch start)."""
    load_optimizer_state(stepper.optimizer, state["optimizer"])
    stepper.load_state_dict(state["data_order"], then=lambda: restore_rng(state["rng"]))
    run = Progress.from_state_dict(state["progress"], policy.device)
    run.resumed_at.append(run.step)
    return run


def _starting_point(cfg: DiffusionPolicyConfig, first_dataset: Path, out_dir: Path, resume: bool):
    """Where the run starts: the interrupted run's resume state (``resume``), a checkpoint to continue from
    (``cfg.init_checkpoint``, refused when trained for another task than ``first_dataset``'s), or nothing; returns
    the config they imply, the resume state and the starting policy."""
    state = load_resume(out_dir) if resume else None
    torch.manual_seed(cfg.seed)
    start = None
    if state is not None:
        cfg = resumed_config(state, cfg)
    elif cfg.init_checkpoint is not None:
        start = DiffusionPolicy.load(cfg.init_checkpoint, device=cfg.device)
        trained, task = start.info.get("task_id"), read_dataset_info(first_dataset)["task_id"]
        if trained not in (None, task):  # before its observation keys are looked for in another task's data
            raise ValueError(
                f"cannot continue from {cfg.init_checkpoint}: it was trained for {trained}, the dataset "
                f"is {task}; train from scratch (no init_checkpoint) or pick a dataset of {trained}"
            )
        cfg = cfg.with_architecture_of(dataclasses.replace(start.cfg, obs_keys=tuple(start.obs_keys)))
    return cfg, state, start


def _read_windows(paths: list[Path], cfg: DiffusionPolicyConfig) -> SequenceDataset:
    """The training windows of the datasets at ``paths``, with a line saying how many and how long they took."""
    read_from = time.perf_counter()
    data = SequenceDataset(
        paths,
        obs_keys=cfg.obs_keys,
        obs_horizon=cfg.obs_horizon,
        pred_horizon=cfg.pred_horizon,
        success_only=cfg.success_only,
        image_keys=cfg.image_keys,
    )
    if cfg.progress and data_parallel.is_main():
        print(
            f"diffusion policy {data.task_id}: {len(data.demos)} demos, {len(data):,} windows read in "
            f"{time.perf_counter() - read_from:.1f} s",
            file=sys.stderr,
            flush=True,
        )
    return data


def _training_log(policy: DiffusionPolicy, data: SequenceDataset, cfg: DiffusionPolicyConfig, run: Progress, stepper):
    """The run's log (``train_log.json``); its summary also goes into the checkpoint (``policy.info["training"]``)."""
    training = {
        "final_loss": run.epochs[-1]["loss"],
        "epochs": len(run.epochs),
        "steps": run.step,
        "wall_time_s": round(run.elapsed_s, 3),
        "init_checkpoint": cfg.init_checkpoint,
        "num_demos": len(data.demos),
        "num_windows": len(data),
        "batch_size": cfg.batch_size,
        "cuda_graph": isinstance(stepper, CudaGraphTrainStep),
        "resumed_at_steps": run.resumed_at,
        "parameters": sum(p.numel() for p in policy.model.parameters()),
        "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
    policy.info["training"] = training
    log = {
        "task_id": data.task_id,
        "dataset": data.source,
        **training,
        "config": cfg.to_dict(),
        "epoch_log": run.epochs,
    }
    return log


def train(
    dataset: str | Path | Any,
    cfg: DiffusionPolicyConfig | dict[str, Any] | None = None,
    *,
    resume: bool = False,
    gpus: int = 1,
) -> Path:
    """Train a diffusion policy on a dataset (a path, an object with ``.path``, or a list of them: same task and
    action columns, trained as one); returns the checkpoint path. ``resume``: continue the interrupted run whose
    resume file is in ``cfg.output_dir`` (same dataset and settings); without it, such a file is refused.
    ``gpus`` > 1: data-parallel over that many processes under torchrun (``newton_lab.policies.data_parallel``;
    ``batch_size`` per process), same checkpoint format."""
    cfg = as_config(cfg)
    many = isinstance(dataset, (list, tuple))
    paths = [Path(getattr(d, "path", d)).expanduser() for d in (dataset if many else [dataset])]
    for path in paths:
        if not path.exists():
            raise FileNotFoundError(f"dataset {path} does not exist; check the path")
    out_dir = Path(cfg.output_dir).expanduser()
    output_path(out_dir / "checkpoint.pt", create=False)  # output_dir (or a folder above it) a file: refused now
    if not resume:
        refuse_fresh_run(out_dir)
    if gpus < 1:
        raise ValueError(f"gpus must be at least 1, got {gpus}")
    if gpus > 1 and data_parallel.world()[1] == 1:
        return data_parallel.launch([str(p) for p in paths], cfg.to_dict(), gpus, resume=resume)
    cfg = dataclasses.replace(cfg, device=data_parallel.join_from_environment(cfg.device))
    if torch.device(cfg.device).type == "cuda" and torch.device(cfg.device).index is not None:
        # the captured step (its side stream, the graph's pool) works on the current device: make it cuda:k
        # (training on cuda:1 from a process whose current device was cuda:0 failed in capture)
        torch.cuda.set_device(torch.device(cfg.device))
    if torch.device(cfg.device).type == "cuda" and cfg.cudnn_benchmark:
        torch.backends.cudnn.benchmark = True  # process-wide: a training runs in a process of its own
    cfg, state, start = _starting_point(cfg, paths[0], out_dir, resume)
    # Ctrl-C / SIGTERM from here on: a resume point after the first step that ends after it; in one process only
    # (ranks would stop at different steps, and the others would wait for them in the next all-reduce; torchrun
    # ends its ranks with SIGTERM, which must stay fatal there)
    with stop_requests() if data_parallel.world()[1] == 1 else nullcontext() as stop:
        data = _read_windows(paths, cfg)
        if state is not None:
            check_resumable(state, cfg, data, out_dir)
            policy = restore_policy(state, cfg)
        elif start is None:
            policy = DiffusionPolicy.from_dataset(data, cfg).to(cfg.device)
        else:
            policy = _continue(start, data, cfg)
        data_parallel.same_start(policy)
        stepper = make_train_step(policy, data, cfg)
        per_epoch = steps_per_epoch(data, cfg.batch_size * data_parallel.world()[1])
        total = per_epoch * cfg.epochs if cfg.max_steps is None else min(per_epoch * cfg.epochs, cfg.max_steps)
        run = Progress(total=total, cap=total) if state is None else _resume(state, policy, stepper)
        if out_dir.is_dir():
            remove_stale_temps(out_dir)
        checkpointer = Checkpointer(cfg, out_dir, policy, stepper, data)
        run_steps(policy, stepper, data.task_id, cfg, run, checkpointer, stop=stop)

    log = _training_log(policy, data, cfg, run, stepper)
    if not data_parallel.is_main():
        return Path(data_parallel.shared(None))
    path = _save_run(policy, out_dir, log)
    checkpointer.finish()
    return Path(data_parallel.shared(str(path)))
