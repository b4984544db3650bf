"""The ``train-rl`` flow: PPO on a task (a cached, resumable stage) -> evaluation of the trained actor on held-out
randomised episodes (the evaluation seed is the run's seed + 10000), with a run record in ``<out>/records/``."""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

from prefect import flow, get_run_logger

from ..records import make_record, write_record
from . import stages
from .run_record import EVAL_SEED_OFFSET, StageClock
from .stage_runs import results, run_evaluate, stage_task

rl_train_task = stage_task(stages.rl_train_stage, "train-rl")


@flow(name="train-rl")
def train_rl(
    task_id: str, ppo: dict[str, Any], out: str = "outputs/ppo", eval_episodes: int = 100, eval_max_steps: int = 1000
) -> dict[str, Any]:
    """PPO (``ppo``: ``newton_lab.policies.rl.train.PPOConfig`` fields) then its evaluation; returns the summary
    (``record``: the run record's path)."""
    log = get_run_logger()
    clock = StageClock()
    (ckpt,), s_train = results([rl_train_task.submit(task_id=task_id, ppo=dict(ppo), out_dir=out)], "train-rl")
    clock.lap("train")
    seed = int(ppo.get("seed", 0))
    metrics, s_eval = run_evaluate(
        ckpt,
        task_id,
        eval_episodes,
        eval_episodes,
        seed + EVAL_SEED_OFFSET,
        ppo.get("device"),
        1,
        eval_max_steps,
        cameras="none",
        task_options=ppo.get("task_options"),
    )
    clock.lap("evaluate")
    log.info(
        "train-rl: %s; evaluation %s: success rate %.1f%% over %d held-out episodes",
        "/".join(s_train),
        "/".join(s_eval),
        100 * metrics["success_rate"],
        metrics["episodes"],
    )
    m = ckpt["metrics"]
    record = make_record(
        "train-rl",
        task=task_id,
        device=ppo.get("device"),
        wall_s=clock.total(),
        results={
            "ppo": dict(ppo),
            "iterations": m.get("iterations"),
            "env_steps": m.get("env_steps"),
            "env_steps_per_s": m.get("env_steps_per_s"),
            "curve_rows": m.get("curve"),
            "timings_s": {**clock.seconds, "flow": clock.total()},
            "success": {
                "episodes": metrics["episodes"],
                "successes": metrics["successes"],
                "rate": metrics["success_rate"],
                "eval_seed": seed + EVAL_SEED_OFFSET,
            },
            "stage_states": {"train": s_train, "evaluate": s_eval},
        },
    )
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%S%fZ")
    path = write_record(record, Path(out) / "records" / f"train-rl-{stamp}.json")
    return {
        "task": task_id,
        "checkpoint": ckpt,
        "evaluation": metrics,
        "record": str(path),
        "stage_states": {"train": s_train, "evaluate": s_eval},
    }
