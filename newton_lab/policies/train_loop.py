"""The optimiser steps of a training run (``run_steps``): the learning-rate schedule (linear warm-up + cosine), a
time budget re-planned into steps as the rate is measured, progress on a terminal or in plain lines, the resume file
written when due (``Checkpointer``) and the epoch log (``Progress``)."""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from tqdm import tqdm

from ..datasets.writers.interrupts import Interrupted
from . import data_parallel
from .data import SequenceDataset
from .diffusion import DiffusionPolicy, DiffusionPolicyConfig
from .resume import (
    RESUME_FORMAT,
    RESUME_VERSION,
    capture_rng,
    data_fingerprint,
    policy_state,
    resume_path,
    write_atomic,
)
from .train_step import CudaGraphTrainStep, EagerTrainStep, set_lr

LOG_EVERY_S = 30.0
"""Seconds between the plain progress lines of a run whose stderr is not a terminal."""


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


def fit_to_budget(step: int, elapsed: float, budget: float, cap: int, rate_from: tuple[int, float], total: int) -> int:
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


def run_steps(
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
                    run.total = fit_to_budget(run.step, elapsed, cfg.time_budget_s, run.cap, run.rate_from, run.total)
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
