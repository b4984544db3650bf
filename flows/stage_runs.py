"""The pipelines' stages as Prefect task runs: each stage function of ``stages`` wrapped as a cached, retried task
(transient errors only), the merge of shard datasets, and the helpers that submit a stage (one run, or shards
with disjoint seed ranges mapped over the flow's task runner) and gather its results. ``orchestration`` (the
single-task pipeline) and ``long_horizon`` (a coherent task's) both build on them.
"""

from __future__ import annotations

import functools
import shutil
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path
from typing import Any

from prefect import get_run_logger, task, unmapped
from prefect.cache_policies import INPUTS

from ..commands import CollectArgs, EvaluateArgs, MimicArgs
from ..datasets import DatasetWriteError
from . import runlog, stages
from .artifacts import artifact
from .settings import PIPELINE_CAMERAS, PIPELINE_DATASET_FORMAT

SEED_STRIDE = 100_000
"""Seed distance between shards: each shard draws from its own seed range."""
EVAL_RECORDED_EPISODES = 2
"""Evaluation episodes the pipeline records to ``<out>/evaluation.rrd`` (the first one of each of as many rows)."""

INPUT_ERRORS = (ValueError, TypeError, KeyError, FileNotFoundError, FileExistsError)
"""Failures caused by a stage's input: a retry would fail the same way, so they are not retried."""
REPORTED_ERRORS = (*INPUT_ERRORS, DatasetWriteError)
"""Failures the command line reports in one line (an input error; a write the disk refused: disk full, a quota):
their tracebacks stay off the console."""


def retry_transient(task, task_run, state) -> bool:
    """Prefect retry condition: retry a failed stage unless it failed on its input (``INPUT_ERRORS``)."""
    try:
        error = state.result(raise_on_failure=False)
    except Exception as exc:  # noqa: BLE001  (a state whose result can't be read back: judge its exception)
        error = exc
    return not isinstance(error, INPUT_ERRORS)


def stage_task(fn, name: str):
    """``fn`` as a cached, retried Prefect task that logs what it does to the run logger."""

    @functools.wraps(fn)
    def run(**kwargs):
        runlog.quiet_console(REPORTED_ERRORS)
        runlog.stage_starting(name)
        log = get_run_logger()
        log.info("%s: %s", name, runlog.describe_inputs(kwargs))
        t0 = time.perf_counter()
        result = fn(**kwargs)
        for line in runlog.describe_result(result, time.perf_counter() - t0):
            log.info("%s: %s", name, line)
        return result

    return task(
        run,
        name=name,
        cache_policy=INPUTS,
        persist_result=True,
        retries=1,
        retry_delay_seconds=1,
        retry_condition_fn=retry_transient,
    )


collect_task = stage_task(stages.collect_stage, "collect")
mimic_task = stage_task(stages.mimic_stage, "mimic")
train_task = stage_task(stages.train_stage, "train")
evaluate_task = stage_task(stages.evaluate_stage, "evaluate")


@task(name="merge", cache_policy=INPUTS, persist_result=True)
def merge_task(shards: list[dict[str, Any]], out_dir: str, name: str) -> dict[str, Any]:
    """Merge shard dataset artifacts into ``<out_dir>/<name>`` (a file name with its format's suffix; ids
    renumbered, provenance kept)."""
    from ..datasets.merge import merge_datasets  # deferred: the dataset package imports Warp/Newton

    path = Path(out_dir) / name
    if path.is_dir():  # a partial merge of an interrupted run; merges are recomputed from their shards
        shutil.rmtree(path)
    elif path.exists():
        path.unlink()
    ref = merge_datasets([s["path"] for s in shards], path)
    total = {
        "attempts": sum(s["metrics"].get("attempts", 0) for s in shards),  # Mimic shards keep successes only
        "successes": sum(s["metrics"].get("successes", s["metrics"]["episodes"]) for s in shards),
    }
    rates = (
        {"generation_success_rate": total["successes"] / max(total["attempts"], 1)}
        if total["attempts"]
        else {"success_rate": total["successes"] / max(ref["episodes"], 1)}
    )
    get_run_logger().info("merge: %d shards -> %s (%d episodes)", len(shards), path, ref["episodes"])
    return artifact(path, "dataset", episodes=ref["episodes"], samples=stages.dataset_samples(path), **total, **rates)


def _split(total: int, parts: int) -> list[int]:
    base, extra = divmod(total, parts)
    return [base + (i < extra) for i in range(parts) if base + (i < extra) > 0]


def shard_args_of(args, shards: int, out: str | None = None, stage: str = "", path_field: str | None = None) -> list:
    """``args`` split into at most ``shards`` argument objects: the episodes divided, disjoint seed ranges and,
    with ``path_field``, one output folder each (``<out>/shards/<stage>_<i>/``, same file name)."""
    parts = []
    for i, n in enumerate(_split(args.episodes, max(shards, 1))):
        moved = (
            {path_field: str(Path(out) / "shards" / f"{stage}_{i}" / Path(getattr(args, path_field)).name)}
            if path_field
            else {}
        )
        parts.append(replace(args, episodes=n, seed=args.seed + SEED_STRIDE * i, **moved))
    return parts


def results(futures, stage: str) -> tuple[list[Any], list[str]]:
    """(results, task state names) of submitted stage runs, once all have ended (the finished ones are cached
    for a re-run); raises the first failure. A run that Dask had to re-run because its worker died is named
    ``<state> (re-run after N lost worker(s))`` and logged as a warning (Prefect's own retries are in each task
    run's state history)."""
    for f in futures:
        f.wait()
    results = [f.result() for f in futures]
    states = []
    for i, f in enumerate(futures):
        lost = _lost_workers(f)
        states.append(f.state.name + (f" (re-run after {lost} lost worker{'s' * (lost > 1)})" if lost else ""))
        if lost:
            get_run_logger().warning(
                "%s run %d of %d: its Dask worker died %d time(s); Dask re-ran it on another worker",
                stage,
                i + 1,
                len(futures),
                lost,
            )
    return results, states


def _lost_workers(future) -> int:
    """Times the Dask worker running ``future``'s task died under it (0 off Dask)."""
    inner = getattr(future, "wrapped_future", None)
    client = getattr(inner, "client", None)
    if client is None or not hasattr(client, "run_on_scheduler"):
        return 0
    return client.run_on_scheduler(_suspicious, key=inner.key)


def _suspicious(key, dask_scheduler=None) -> int:
    """On the Dask scheduler: how often ``key`` was running on a worker that died."""
    ts = dask_scheduler.tasks.get(key)
    return 0 if ts is None else ts.suspicious


def run_dataset_stage(
    stage_task, args, *, shards: int, out: str, stage: str, path_field: str, **fixed
) -> tuple[dict[str, Any], list[str]]:
    """Submit a dataset stage (one run, or ``shards`` runs merged into ``<out>/<the file name of args'
    path_field>``); returns (artifact, state names: shards, then the merge). The artifact goes downstream unchanged
    (it is the next stage's cache key) and is published as the stage's artifact."""
    name = Path(getattr(args, path_field)).name
    if shards <= 1:
        (art,), states = results([stage_task.submit(args=args, **fixed)], stage)
    else:
        parts, states = results(
            stage_task.map(
                args=shard_args_of(args, shards, out, stage, path_field), **{k: unmapped(v) for k, v in fixed.items()}
            ),
            stage,
        )
        (art,), merged = results([merge_task.submit(shards=parts, out_dir=out, name=name)], "merge")
        states = states + merged
    runlog.publish_dataset(stage, art, shards)
    return art, states


def run_collect(
    task_id,
    episodes,
    num_envs,
    seed,
    device,
    out,
    shards,
    *,
    cameras=PIPELINE_CAMERAS,
    task_options=None,
    max_steps=None,
    domain_randomize=None,
    dataset_format=PIPELINE_DATASET_FORMAT,
    distractors=0,
):
    """Collect ``episodes`` expert demos on at most ``num_envs`` rows (no more rows than demos) into
    ``<out>/demos.<dataset_format>``; with ``domain_randomize`` (axis -> level) each row draws its own physics and
    camera offsets (collect's flag); ``distractors`` objects stand on the table."""
    args = CollectArgs(
        task=task_id,
        episodes=episodes,
        num_envs=min(num_envs, episodes),
        seed=seed,
        device=device,
        randomize=True,
        dataset_path=str(Path(out) / f"demos.{dataset_format}"),
        cameras=cameras,
        task_options=dict(task_options or {}),
        distractors=distractors,
        **({"max_steps": max_steps} if max_steps else {}),
        **(
            {"domain_randomize": ",".join(f"{k}={v:g}" for k, v in domain_randomize.items())}
            if domain_randomize
            else {}
        ),
    )
    return run_dataset_stage(collect_task, args, shards=shards, out=out, stage="collect", path_field="dataset_path")


def run_mimic(
    source,
    episodes,
    num_envs,
    seed,
    device,
    out,
    shards,
    *,
    cameras=PIPELINE_CAMERAS,
    dataset_format=PIPELINE_DATASET_FORMAT,
):
    """Grow ``source`` to ``episodes`` Mimic demos on at most ``num_envs`` rows into
    ``<out>/mimic.<dataset_format>``, rendering ``cameras`` (the source's task options, ``obs_mode`` included, are
    kept)."""
    args = MimicArgs(
        dataset_path=source["path"],
        output_path=str(Path(out) / f"mimic.{dataset_format}"),
        episodes=episodes,
        num_envs=min(num_envs, episodes),
        seed=seed,
        device=device,
        cameras=cameras,
    )
    return run_dataset_stage(
        mimic_task, args, shards=shards, out=out, stage="mimic", path_field="output_path", source=source
    )


def run_train(dataset, train_cfg, out, gpus=1):
    (ckpt,), states = results(
        [train_task.submit(dataset=dataset, train_cfg=dict(train_cfg or {}), out_dir=out, gpus=gpus)], "train"
    )
    runlog.publish_loss_curve(ckpt)
    return ckpt, states


def run_evaluate(
    checkpoint,
    task_id,
    episodes,
    num_envs,
    seed,
    device,
    shards,
    max_steps,
    recording=None,
    *,
    cameras=PIPELINE_CAMERAS,
    task_options=None,
    phase_checkpoints=None,
):
    """Evaluate a checkpoint artifact, or a coherent task's ``phase_checkpoints`` (phase -> artifact; checkpoint
    None), in ``shards`` runs with disjoint seeds; the summed metrics (per phase too) and the task states."""
    args = EvaluateArgs(
        task=task_id,
        checkpoint=None if checkpoint is None else checkpoint["path"],
        episodes=episodes,
        num_envs=min(num_envs, episodes),
        seed=seed,
        device=device,
        randomize=True,
        max_steps=max_steps,
        cameras=cameras,
        task_options=dict(task_options or {}),
    )
    shard_args = shard_args_of(args, shards)
    if recording is not None:  # two episodes of the first shard, for the viewer
        shard_args[0] = replace(shard_args[0], rerun_save=str(recording), rerun_worlds=EVAL_RECORDED_EPISODES)
    parts, states = results(
        evaluate_task.map(
            checkpoint=unmapped(checkpoint), args=shard_args, phase_checkpoints=unmapped(phase_checkpoints)
        ),
        "evaluate",
    )
    n = sum(p["episodes"] for p in parts)
    ok = sum(p["successes"] for p in parts)
    metrics = {
        "episodes": n,
        "successes": ok,
        "success_rate": ok / max(n, 1),
        "termination_reasons": summed(p["termination_reasons"] for p in parts),
        "subtask_signals": summed(p.get("subtask_signals", {}) for p in parts),
        "phases": {
            name: {
                "reached": sum(p["phases"][name]["reached"] for p in parts),
                "passed": sum(p["phases"][name]["passed"] for p in parts),
                "stalled": summed(p["phases"][name]["stalled"] for p in parts),
            }
            for name in parts[0]["phases"]
        },
        "average_length": sum(p["average_length"] * p["episodes"] for p in parts) / max(n, 1),
    }
    if any(p.get("phase_targets") for p in parts):  # per phase kind and target (SortToShelf-All: per object)
        metrics["phase_targets"] = summed_by_target(p.get("phase_targets", {}) for p in parts)
    recorded = [p["recording"] for p in parts if p.get("recording")]
    if recorded:
        metrics["recording"] = recorded[0]
    runlog.publish_evaluation(metrics)
    return metrics, states


def summed_by_target(tables) -> dict[str, dict[str, dict[str, int]]]:
    """Evaluations' ``phase_targets`` (kind -> target -> reached / passed) added up."""
    out: dict[str, dict[str, dict[str, int]]] = {}
    for table in tables:
        for kind, by_value in table.items():
            for value, cell in by_value.items():
                into = out.setdefault(kind, {}).setdefault(value, {"reached": 0, "passed": 0})
                into["reached"] += cell["reached"]
                into["passed"] += cell["passed"]
    return out


def summed(counts) -> dict[str, int]:
    """Counters (name -> count) added up; a name counted 0 everywhere is kept."""
    total: Counter[str] = Counter()
    for c in counts:
        total.update(c)
    return dict(total)
