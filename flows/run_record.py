"""The run record of a pipeline (``newton_lab.records``): the flow's counts, per-stage wall times, success with
its episodes and evaluation seed, and the per-phase table, written to ``<out>/records/<UTC time>.json`` (a re-run
adds its own record: one answered from cache shows stages ``Cached`` and seconds, and replaces nothing)."""

from __future__ import annotations

import datetime as dt
import json
import time
from pathlib import Path
from typing import Any

from ..records import command_wall_s, make_record, write_record

EVAL_SEED_OFFSET = 10_000
"""The evaluation's seed is the pipeline's seed plus this (the collection and Mimic never draw from it)."""


class StageClock:
    """Wall seconds of each stage of one flow run, in the order they ran."""

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.seconds: dict[str, float] = {}
        self._last = self.t0

    def lap(self, stage: str) -> None:
        """The stage that just ended took the time since the previous lap."""
        now = time.perf_counter()
        self.seconds[stage] = round(now - self._last, 2)
        self._last = now

    def total(self) -> float:
        return round(time.perf_counter() - self.t0, 2)


def pipeline_record(
    summary: dict[str, Any],
    clock: StageClock,
    *,
    seed: int,
    device: str | None,
    train_cfg: dict[str, Any],
    cameras: str,
    task_options: dict[str, Any],
    recipe: str | None,
    domain_randomize: dict[str, float] | None = None,
    dataset_format: str | None = None,
    distractors: int = 0,
    per_target: list[str] | None = None,
) -> dict[str, Any]:
    """The record of a finished pipeline run (single-task or long-horizon) from its summary (``domain_randomize``:
    the levels its collection drew, ``distractors``: the objects it stood among, and ``per_target``: the phase kinds
    trained one policy per target, each recorded only when given; ``dataset_format``: its datasets' format)."""
    arts, ev = summary["artifacts"], summary["evaluation"]
    demos = arts["demos"]["metrics"]
    counts: dict[str, Any] = {"expert_demos": demos.get("episodes"), "expert_success_rate": demos.get("success_rate")}
    if "mimic" in arts:
        m = arts["mimic"]["metrics"]
        counts.update(mimic_demos=m.get("episodes"), mimic_attempts=m.get("attempts"))
    checkpoints = arts.get("checkpoints") or {"policy": arts["checkpoint"]}
    counts["train_steps"] = {name: c["metrics"].get("steps") for name, c in checkpoints.items()}
    results = {
        "recipe": recipe,
        "seed": seed,
        "cameras": cameras,
        "task_options": task_options,
        **({"domain_randomize": domain_randomize} if domain_randomize else {}),
        **({"distractors": distractors} if distractors else {}),
        **({"per_target": per_target} if per_target else {}),
        "dataset_format": dataset_format,
        "train": {k: v for k, v in train_cfg.items() if k not in ("output_dir",)},
        "learned_phases": summary.get("learned_phases"),
        "counts": counts,
        "timings_s": {**clock.seconds, "flow": clock.total()},
        "collect_seconds": demos.get("seconds"),  # where the collect stage's time went (stages.COLLECT_SECONDS)
        "success": {
            "episodes": ev["episodes"],
            "successes": ev["successes"],
            "rate": ev["success_rate"],
            "eval_seed": seed + EVAL_SEED_OFFSET,
            "average_length": ev.get("average_length"),
            "termination_reasons": ev.get("termination_reasons"),
        },
        "phases": ev.get("phases"),
        "subtask_signals": ev.get("subtask_signals"),  # episodes each fired in (SortToShelf-All: per object)
        **({"phase_targets": ev["phase_targets"]} if ev.get("phase_targets") else {}),  # per kind and target
        "stage_states": summary["stage_states"],
    }
    wall = command_wall_s()
    return make_record(
        "pipeline", task=summary["task"], device=device, results=results, wall_s=clock.total() if wall is None else wall
    )


def write_pipeline_record(record: dict[str, Any], out_dir: Path) -> Path:
    """``<out_dir>/records/<UTC time>.json``."""
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%S%fZ")
    return write_record(record, Path(out_dir) / "records" / f"pipeline-{stamp}.json")


def record_run(summary: dict[str, Any], clock: StageClock, out_dir: Path, **settings) -> dict[str, Any]:
    """``summary`` (a pipeline flow's result) with its run record written into ``<out_dir>/records/``
    (``pipeline_record``'s ``settings``) and ``summary["record"]`` naming it, and ``<out_dir>/metrics.json``."""
    summary["record"] = str(write_pipeline_record(pipeline_record(summary, clock, **settings), out_dir))
    (out_dir / "metrics.json").write_text(json.dumps(summary, indent=1))
    return summary
