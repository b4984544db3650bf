"""Prefect flows: ``collect``, ``mimic``, ``train``, ``evaluate`` and ``pipeline`` chaining them.

Each stage is a Prefect task over artifacts (path + content hash) cached on its inputs, so a re-run of
the same pipeline is answered from the cache (task state ``Cached``) and a failed stage is retried alone
(transient errors only: input errors fail at once). Stages log to Prefect's run logger and each publishes
its artifact (``runlog``). Every stage is submitted to the flow's task runner: with ``runner="dask"``,
collection, Mimic and evaluation are split into shards with disjoint seed ranges, mapped over a Dask
cluster (a local one sized by ``cluster.cluster_options``, or the scheduler ``address`` given), and shard
datasets are merged into one; ``pipeline`` runs the stages itself (no sub-flows), so all of them share its
task runner and its one cluster.
"""

from __future__ import annotations

import socket
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from prefect import flow, get_run_logger

from ..commands import PipelineArgs
from ..datasets.files.output_paths import output_path
from ..task_api.registry import lookup
from . import runlog
from .cluster import cluster_options, pins_gpus, quiet_shutdown
from .long_horizon import has_phases, long_horizon_pipeline
from .run_record import StageClock, record_run
from .settings import DEMO_RECIPES, PIPELINE_CAMERAS, PIPELINE_DATASET_FORMAT, check_api_reachable
from .stage_runs import (
    REPORTED_ERRORS,
    collect_task,
    evaluate_task,
    mimic_task,
    run_collect,
    run_evaluate,
    run_mimic,
    run_train,
    train_task,
)

VALID_RUNNERS = ("local", "dask")

_P = PipelineArgs()
"""The pipeline's defaults: the ones of ``newton-lab pipeline``."""
_R = DEMO_RECIPES["cpu"]
"""The flow's default counts: the cpu demo recipe's (``newton-lab pipeline`` resolves its recipe itself)."""


def _check_counts(**counts: Any) -> None:
    """Episode / step counts must be integers >= 1 (checked before the flow starts: nothing is written)."""
    for name, value in counts.items():
        if value is not None and (not isinstance(value, int) or isinstance(value, bool) or value < 1):
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")


def _check(task_id: str, runner: str, workers: int) -> None:
    from .. import tasks  # noqa: F401  deferred: registering the task ids imports Warp

    lookup(task_id)
    if runner not in VALID_RUNNERS:
        raise ValueError(f"unknown runner {runner!r}; valid runners: {', '.join(VALID_RUNNERS)}")
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")


@flow(name="collect")
def collect(
    task_id: str,
    episodes: int = 4,
    num_envs: int = 2,
    seed: int = 0,
    device: str | None = None,
    out: str = "outputs/pipeline",
    shards: int = 1,
) -> tuple[dict[str, Any], list[str]]:
    """Expert demos of ``task_id`` (randomised) -> (dataset artifact, task states); ``shards`` > 1: disjoint
    seeds, merged."""
    return run_collect(task_id, episodes, num_envs, seed, device, out, shards)


@flow(name="mimic")
def mimic(
    source: dict[str, Any],
    episodes: int = 40,
    num_envs: int = 4,
    seed: int = 1,
    device: str | None = None,
    out: str = "outputs/pipeline",
    shards: int = 1,
) -> tuple[dict[str, Any], list[str]]:
    """Mimic expansion of a dataset artifact -> (dataset artifact, task states)."""
    return run_mimic(source, episodes, num_envs, seed, device, out, shards)


@flow(name="train")
def train(
    dataset: dict[str, Any], train_cfg: dict[str, Any] | None = None, out: str = "outputs/pipeline"
) -> tuple[dict[str, Any], list[str]]:
    """Diffusion policy on a dataset artifact -> (checkpoint artifact, task states)."""
    return run_train(dataset, train_cfg, out)


@flow(name="evaluate")
def evaluate(
    checkpoint: dict[str, Any],
    task_id: str,
    episodes: int = 10,
    num_envs: int = 5,
    seed: int = 10_000,
    device: str | None = None,
    shards: int = 1,
    max_steps: int = 600,
) -> tuple[dict[str, Any], list[str]]:
    """Success rate of a checkpoint artifact (randomised; ``shards`` > 1: disjoint seeds, summed) -> (metrics,
    task states)."""
    return run_evaluate(checkpoint, task_id, episodes, num_envs, seed, device, shards, max_steps)


@flow(name="pipeline")
def pipeline(
    task_id: str = _P.task,
    demos: int = _R["demos"],
    mimic_episodes: int = _R["mimic_episodes"],
    train_cfg: dict[str, Any] | None = None,
    eval_episodes: int = _R["eval_episodes"],
    num_envs: int = _R["num_envs"],
    device: str | None = _P.device,
    out: str = _P.out,
    seed: int = _P.seed,
    workers: int = _P.workers,
    eval_max_steps: int = 600,
    gpus: int = 1,
    record: bool = _P.record,
    cameras: str = PIPELINE_CAMERAS,
    task_options: dict[str, Any] | None = None,
    recipe: str | None = None,
    dataset_format: str = PIPELINE_DATASET_FORMAT,
) -> dict[str, Any]:
    """collect -> mimic -> train -> evaluate for ``task_id``, each stage a task run of this flow (one task
    runner for all); publishes one artifact per stage and a markdown summary (``runlog``), writes
    ``<out>/metrics.json`` and a run record (``<out>/records/``; ``summary["record"]``). ``workers`` > 1 shards
    collection, Mimic and evaluation. ``cameras`` are rendered and recorded by collection, Mimic and evaluation
    (a visuomotor recipe); ``task_options`` (e.g. ``obs_mode="sensors"``) apply to every env; ``dataset_format``
    (hdf5 or zarr) is that of the demos and the Mimic demos.
    Defaults are ``PipelineArgs``'s (``newton-lab pipeline``); ``train_cfg`` None is the policy's default."""
    runlog.quiet_console(REPORTED_ERRORS)
    runlog.restore_caller_sigterm()
    log = get_run_logger()
    out_dir = output_path(Path(out) / "metrics.json").parent
    options = dict(task_options or {})
    clock = StageClock()
    data = {"cameras": cameras, "dataset_format": dataset_format}  # what collection and Mimic render and write
    demo_art, s_collect = run_collect(
        task_id, demos, num_envs, seed, device, out, workers, task_options=options, **data
    )
    clock.lap("collect")
    log.info("collect: %s", "/".join(s_collect))
    gen_art, s_mimic = run_mimic(demo_art, mimic_episodes, num_envs, seed + 1, device, out, workers, **data)
    clock.lap("mimic")
    log.info("mimic: %s", "/".join(s_mimic))
    ckpt_art, s_train = run_train(gen_art, train_cfg, out, gpus)
    clock.lap("train")
    log.info("train: %s", "/".join(s_train))
    metrics, s_eval = run_evaluate(
        ckpt_art,
        task_id,
        eval_episodes,
        num_envs,
        seed + 10_000,
        device,
        workers,
        eval_max_steps,
        recording=Path(out) / "evaluation.rrd" if record else None,
        cameras=cameras,
        task_options=options,
    )
    clock.lap("evaluate")
    log.info(
        "evaluate: %s; success rate %.1f%% over %d episodes",
        "/".join(s_eval),
        100 * metrics["success_rate"],
        metrics["episodes"],
    )
    summary = {
        "task": task_id,
        "success_rate": metrics["success_rate"],
        "evaluation": metrics,
        "artifacts": {"demos": demo_art, "mimic": gen_art, "checkpoint": ckpt_art},
        "stage_states": {"collect": s_collect, "mimic": s_mimic, "train": s_train, "evaluate": s_eval},
    }
    settings = {"seed": seed, "device": (train_cfg or {}).get("device", device), "train_cfg": dict(train_cfg or {})}
    record_run(summary, clock, out_dir, **settings, **data, task_options=options, recipe=recipe)
    runlog.publish_summary(task_id, demo_art, gen_art, ckpt_art, metrics, out_dir)
    return summary


def run_pipeline(
    *,
    runner: str = _P.runner,
    workers: int = _P.workers,
    address: str | None = _P.address,
    retries: int = _P.retries,
    **kwargs,
) -> dict[str, Any]:
    """Run ``pipeline`` with the chosen task runner: ``local`` (threads in this process) or ``dask``
    (a local cluster of ``workers`` processes, or the scheduler at ``address``). ``PipelineArgs.pipeline_kwargs()``
    gives every keyword from the command line's arguments."""
    _check(kwargs.get("task_id", _P.task), runner, workers)
    _check_counts(
        **{k: kwargs.get(k) for k in ("demos", "mimic_episodes", "eval_episodes", "num_envs", "eval_max_steps", "gpus")}
    )
    flow_fn = pipeline
    if has_phases(kwargs.get("task_id", _P.task)):
        if kwargs.pop("mimic_episodes", None) is not None:
            raise ValueError(
                "a coherent task's pipeline takes more coherent demos (--demos) instead of Mimic; drop --mimic-episodes"
            )
        flow_fn = long_horizon_pipeline
    check_api_reachable()
    options: dict[str, Any] = {}
    if runner == "dask":
        from prefect_dask import DaskTaskRunner  # deferred: Dask is slow to import and only the dask runner needs it

        if address:
            _check_scheduler(address)
            options["task_runner"] = DaskTaskRunner(address=address)
        else:
            cluster = cluster_options(workers, kwargs.get("device"))
            quiet_shutdown()
            options["task_runner"] = DaskTaskRunner(**cluster)
            if "workers" in cluster["cluster_kwargs"] and pins_gpus(kwargs.get("device")):
                kwargs["device"] = "cuda"  # each worker's own GPU
    for t in (collect_task, mimic_task, train_task, evaluate_task):
        t.retries = retries
    runlog.quiet_console(REPORTED_ERRORS)
    runlog.note_caller_sigterm()
    return flow_fn.with_options(**options)(workers=workers if runner == "dask" else 1, **kwargs)


def _check_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Fail within ``timeout_s`` with a one-line error when the Dask scheduler is unreachable."""
    u = urlparse(address if "://" in address else f"tcp://{address}")
    try:
        socket.create_connection((u.hostname, u.port or 8786), timeout=timeout_s).close()
    except OSError as exc:
        raise ConnectionError(f"Dask scheduler {address} is unreachable ({exc}); start it or drop --address") from None
