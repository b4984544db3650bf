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
import math
import os
import sys
import time
import warnings
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from tqdm import tqdm

from ..datasets import read_dataset_info
from ..datasets.files.output_paths import output_path
from ..datasets.writers.interrupts import Interrupted, stop_requests
from . import data_parallel
from .data import SequenceDataset
from .diffusion import DiffusionPolicy, DiffusionPolicyConfig
from .resume import (
    RESUME_FORMAT,
    RESUME_VERSION,
    capture_rng,
    check_resumable,
    data_fingerprint,
    load_resume,
    policy_state,
    refuse_fresh_run,
    remove_stale_temps,
    restore_policy,
    restore_rng,
    resume_path,
    resumed_config,
    write_atomic,
)
from .train_step import (
    CudaGraphTrainStep,
    EagerTrainStep,
    load_optimizer_state,
    make_train_step,
    set_lr,
    steps_per_epoch,
)

LOG_EVERY_S = 30.0
"""Seconds between the plain progress lines of a run whose stderr is not a terminal."""


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


def _fit_to_budget(step: int, elapsed: float, budget: float, cap: int, rate_from: tuple[int, float], total: int) -> int:
    """Planned total steps so the loop ends within ``budget`` seconds: re-planned at step 50 (rate over the
    first 50 steps), then every 100 steps from the rate since step 50 (the machine may speed up or slow
    down; each re-plan moves the cosine schedule only a little); never above ``cap``."""
    start, t_start = rate_from
    if not _replans_at(step, start):
        return total
    rate = step / elapsed if step == start else (step - start) / max(elapsed - t_start, 1e-9)
    return min(cap, step + max(0, int((budget - elapsed) * rate * 0.97)))  # == step: stop now


def _replans_at(step: int, start: int) -> bool:
    """Whether a time-budgeted run re-plans its total at ``step`` (``start``: the step its rate is measured from)."""
    return step == start or (step > start and step % 100 == 0)


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


@dataclass
class Progress:
    """The loop's own state (saved in the resume file): steps, the planned total (re-planned to a time budget),
    the epoch log and the running epoch's step losses (device tensors, read back at the epoch end)."""

    total: int
    cap: int
    step: int = 0
    rate_from: tuple[int, float] = (50, 0.0)  # (step, time): the rate is measured after the first 50 steps
    epochs: list[dict[str, Any]] = field(default_factory=list)
    losses: list[torch.Tensor] = field(default_factory=list)
    elapsed_s: float = 0.0
    resumed_at: list[int] = field(default_factory=list)

    def state_dict(self) -> dict[str, Any]:
        return {
            "total": self.total,
            "cap": self.cap,
            "step": self.step,
            "rate_from": tuple(self.rate_from),
            "epochs": self.epochs,
            "elapsed_s": self.elapsed_s,
            "resumed_at": self.resumed_at,
            "losses": torch.stack(self.losses).cpu() if self.losses else torch.zeros(0),
        }

    @classmethod
    def from_state_dict(cls, state: dict[str, Any], device: torch.device) -> Progress:
        return cls(
            **{
                **state,
                "rate_from": tuple(state["rate_from"]),
                "epochs": list(state["epochs"]),
                "resumed_at": list(state["resumed_at"]),
                "losses": list(state["losses"].to(device).unbind()),
            }
        )


class Checkpointer:
    """Writes the resume file when due: every ``checkpoint_every_steps`` steps or ``checkpoint_every_s`` seconds."""

    def __init__(
        self,
        cfg: DiffusionPolicyConfig,
        out_dir: Path,
        policy: DiffusionPolicy,
        stepper: EagerTrainStep | CudaGraphTrainStep,
        data: SequenceDataset,
    ) -> None:
        self.cfg, self.path, self.policy, self.stepper, self.data = cfg, resume_path(out_dir), policy, stepper, data
        self.last = time.perf_counter()
        self.fingerprint: str | None = None

    def due(self, step: int) -> bool:
        every_steps, every_s = self.cfg.checkpoint_every_steps, self.cfg.checkpoint_every_s
        return bool(
            (every_steps and step % every_steps == 0) or (every_s and time.perf_counter() - self.last >= every_s)
        )

    def save(self, progress: Progress) -> None:
        self.fingerprint = self.fingerprint or data_fingerprint(self.data)
        payload = {
            "format": RESUME_FORMAT,
            "version": RESUME_VERSION,
            "config": self.cfg.to_dict(),
            "policy": policy_state(self.policy),
            "optimizer": self.stepper.optimizer.state_dict(),
            "data_order": self.stepper.state_dict(),
            "progress": progress.state_dict(),
            "rng": capture_rng(),
            "data": {"fingerprint": self.fingerprint, "source": self.data.source},
        }
        write_atomic(payload, self.path)
        self.last = time.perf_counter()

    def finish(self) -> None:
        """The run's final checkpoint is written: its resume file has served."""
        self.path.unlink(missing_ok=True)


def _loop(
    policy: DiffusionPolicy,
    stepper: EagerTrainStep | CudaGraphTrainStep,
    task_id: str,
    cfg: DiffusionPolicyConfig,
    run: Progress,
    checkpointer: Checkpointer,
    stop=None,
) -> None:
    """Optimiser steps until ``run.total`` (re-planned to ``cfg.time_budget_s``), from ``run.step`` on. ``stop``
    (``datasets.writers.interrupts.StopRequest``) set: the resume point is saved after the step in flight and
    ``Interrupted`` raised."""
    lr_factor = warmup_cosine(cfg.warmup_steps, lambda: run.total)
    t0 = time.perf_counter() - run.elapsed_s  # a resumed run's budget counts the time before the interruption
    policy.model.train()
    set_lr(stepper.optimizer, cfg.lr * lr_factor(run.step))
    processes, show = data_parallel.world()[1], cfg.progress and data_parallel.is_main()
    with tqdm(
        total=run.total,
        initial=run.step,
        desc=f"diffusion policy {task_id}",
        unit="step",
        disable=None if show else True,
    ) as bar:  # None: a terminal only (no \r bars in logs)
        lines = show and bar.disable  # not a terminal (a log file, Prefect): a plain line every LOG_EVERY_S
        last_line = time.perf_counter()
        while run.step < run.total:
            for loss in stepper.epoch():
                run.losses.append(loss)  # no host sync per step: read back every 50 steps
                run.step += 1
                bar.update()
                if lines and time.perf_counter() - last_line >= LOG_EVERY_S:
                    last_line = time.perf_counter()
                    rate = run.step * cfg.batch_size * processes / max(last_line - t0, 1e-9)
                    print(
                        f"diffusion policy {task_id}: step {run.step}/{run.total}, loss {loss.item():.4f}, "
                        f"{rate:,.0f} samples/s, {last_line - t0:.0f} s",
                        file=sys.stderr,
                        flush=True,
                    )
                if cfg.time_budget_s is not None:
                    elapsed = time.perf_counter() - t0
                    run.total = _fit_to_budget(run.step, elapsed, cfg.time_budget_s, run.cap, run.rate_from, run.total)
                    if _replans_at(run.step, run.rate_from[0]):  # the same steps on every rank: rank 0's plan counts
                        run.total = data_parallel.shared(run.total)
                    if run.step == run.rate_from[0]:
                        run.rate_from = (run.step, elapsed)
                    bar.total = run.total
                if run.step % 50 == 0:
                    bar.set_postfix(loss=f"{run.losses[-1].item():.4f}", epoch=len(run.epochs) + 1, refresh=False)
                if run.step >= run.total:
                    break
                set_lr(stepper.optimizer, cfg.lr * lr_factor(run.step))
                if (checkpointer.due(run.step) or stop) and data_parallel.is_main():
                    run.elapsed_s = time.perf_counter() - t0
                    checkpointer.save(run)
                if stop:
                    raise Interrupted(
                        f"interrupted at step {run.step} of {run.total}: the resume point is saved in "
                        f"{checkpointer.path}; continue with --resume",
                        stop.signum,
                    )
            run.epochs.append(
                {
                    "epoch": len(run.epochs) + 1,
                    "loss": data_parallel.mean_over_ranks(torch.stack(run.losses).mean()).item(),
                    "steps": run.step,
                    "lr": cfg.lr * lr_factor(run.step),
                }
            )
            run.losses = []
    run.elapsed_s = time.perf_counter() - t0


def _resume(state: dict[str, Any], policy: DiffusionPolicy, stepper: EagerTrainStep | CudaGraphTrainStep) -> Progress:
    """Optimizer, data order and loop state of the interrupted run; its RNG states are restored when the first
    resumed epoch has rewound its data order (the DataLoader draws from them at an epoch start)."""
    load_optimizer_state(stepper.optimizer, state["optimizer"])
    stepper.load_state_dict(state["data_order"], then=lambda: restore_rng(state["rng"]))
    run = Progress.from_state_dict(state["progress"], policy.device)
    run.resumed_at.append(run.step)
    return run


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
    state = load_resume(out_dir) if resume else None
    torch.manual_seed(cfg.seed)
    start = None
    if state is not None:
        cfg = resumed_config(state, cfg)
    elif cfg.init_checkpoint is not None:
        start = DiffusionPolicy.load(cfg.init_checkpoint, device=cfg.device)
        trained, task = start.info.get("task_id"), read_dataset_info(paths[0])["task_id"]
        if trained not in (None, task):  # before its observation keys are looked for in another task's data
            raise ValueError(
                f"cannot continue from {cfg.init_checkpoint}: it was trained for {trained}, the dataset "
                f"is {task}; train from scratch (no init_checkpoint) or pick a dataset of {trained}"
            )
        cfg = cfg.with_architecture_of(dataclasses.replace(start.cfg, obs_keys=tuple(start.obs_keys)))
    # Ctrl-C / SIGTERM from here on: a resume point after the first step that ends after it; in one process only
    # (ranks would stop at different steps, and the others would wait for them in the next all-reduce; torchrun
    # ends its ranks with SIGTERM, which must stay fatal there)
    with stop_requests() if data_parallel.world()[1] == 1 else nullcontext() as stop:
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
        _loop(policy, stepper, data.task_id, cfg, run, checkpointer, stop=stop)

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
    if not data_parallel.is_main():
        return Path(data_parallel.shared(None))
    path = _save_run(policy, out_dir, log)
    checkpointer.finish()
    return Path(data_parallel.shared(str(path)))
