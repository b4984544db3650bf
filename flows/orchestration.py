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

import functools
import json
import socket
import time
from dataclasses import replace
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from prefect import flow, get_run_logger, task, unmapped
from prefect.cache_policies import INPUTS

from ..commands import CollectArgs, EvaluateArgs, MimicArgs, PipelineArgs
from ..datasets.outputs import output_path
from ..task_api.registry import lookup
from . import runlog, stages
from .artifacts import artifact
from .cluster import cluster_options, pins_gpus, quiet_shutdown
from .settings import DEMO_RECIPES, PIPELINE_CAMERAS, check_api_reachable

SEED_STRIDE = 100_000
"""Seed distance between shards: each shard draws from its own seed range."""
EVAL_RECORDED_EPISODES = 2
"""Evaluation episodes the pipeline records to ``<out>/evaluation.rrd`` (the first one of each of as many rows)."""

VALID_RUNNERS = ("local", "dask")

_P = PipelineArgs()
"""The pipeline's defaults: the ones of ``newton-lab pipeline``."""
_R = DEMO_RECIPES["cpu"]
"""The flow's default counts: the cpu demo recipe's (``newton-lab pipeline`` resolves its recipe itself)."""


INPUT_ERRORS = (ValueError, TypeError, KeyError, FileNotFoundError, FileExistsError)
"""Failures caused by a stage's input: a retry would fail the same way, so they are not retried."""


def retry_transient(task, task_run, state) -> bool:
    """Prefect retry condition: retry a failed stage unless it failed on its input (``INPUT_ERRORS``)."""
    try:
        error = state.result(raise_on_failure=False)
    except Exception as exc:  # noqa: BLE001  (a state whose result can't be read back: judge its exception)
        error = exc
    return not isinstance(error, INPUT_ERRORS)


def _stage_task(fn, name: str):
    """``fn`` as a cached, retried Prefect task that logs what it does to the run logger."""

    @functools.wraps(fn)
    def run(**kwargs):
        runlog.quiet_console(INPUT_ERRORS)
        runlog.fault_point(name)
        log = get_run_logger()
        log.info("%s: %s", name, runlog.describe_inputs(kwargs))
        t0 = time.perf_counter()
        result = fn(**kwargs)
        for line in runlog.describe_result(result, time.perf_counter() - t0):
            log.info("%s: %s", name, line)
        return result

    return task(run, name=name, cache_policy=INPUTS, persist_result=True, retries=1, retry_delay_seconds=1,
                retry_condition_fn=retry_transient)


collect_task = _stage_task(stages.collect_stage, "collect")
mimic_task = _stage_task(stages.mimic_stage, "mimic")
train_task = _stage_task(stages.train_stage, "train")
evaluate_task = _stage_task(stages.evaluate_stage, "evaluate")


@task(name="merge", cache_policy=INPUTS, persist_result=True)
def merge_task(shards: list[dict[str, Any]], out_dir: str, name: str) -> dict[str, Any]:
    """Merge shard dataset artifacts into ``<out_dir>/<name>.hdf5`` (ids renumbered, provenance kept)."""
    from ..datasets.merge import merge_datasets  # deferred: the dataset package imports Warp/Newton

    path = Path(out_dir) / f"{name}.hdf5"
    if path.exists():
        path.unlink()  # a partial merge of an interrupted run; merges are recomputed from their shards
    ref = merge_datasets([s["path"] for s in shards], path)
    total = {"attempts": sum(s["metrics"].get("attempts", 0) for s in shards),  # Mimic shards keep successes only
             "successes": sum(s["metrics"].get("successes", s["metrics"]["episodes"]) for s in shards)}
    rates = ({"generation_success_rate": total["successes"] / max(total["attempts"], 1)} if total["attempts"]
             else {"success_rate": total["successes"] / max(ref["episodes"], 1)})
    get_run_logger().info("merge: %d shards -> %s (%d episodes)", len(shards), path, ref["episodes"])
    return artifact(path, "dataset", episodes=ref["episodes"], samples=stages.dataset_samples(path), **total,
                    **rates)


def _split(total: int, parts: int) -> list[int]:
    base, extra = divmod(total, parts)
    return [base + (i < extra) for i in range(parts) if base + (i < extra) > 0]


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


def _shards(args, shards: int, out: str | None = None, stage: str = "", path_field: str | None = None) -> list:
    """``args`` split into at most ``shards`` argument objects: the episodes divided, disjoint seed ranges and,
    with ``path_field``, one output folder each (``<out>/shards/<stage>_<i>/``, same file name)."""
    parts = []
    for i, n in enumerate(_split(args.episodes, max(shards, 1))):
        moved = ({path_field: str(Path(out) / "shards" / f"{stage}_{i}" / Path(getattr(args, path_field)).name)}
                 if path_field else {})
        parts.append(replace(args, episodes=n, seed=args.seed + SEED_STRIDE * i, **moved))
    return parts


def _results(futures, stage: str) -> tuple[list[Any], list[str]]:
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
            get_run_logger().warning("%s run %d of %d: its Dask worker died %d time(s); Dask re-ran it on another "
                                     "worker", stage, i + 1, len(futures), lost)
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


def _run_dataset_stage(stage_task, args, *, shards: int, out: str, stage: str, name: str, path_field: str,
                       **fixed) -> tuple[dict[str, Any], list[str]]:
    """Submit a dataset stage (one run, or ``shards`` runs merged into ``<out>/<name>.hdf5``); returns
    (artifact, state names: shards, then the merge). The artifact goes downstream unchanged (it is the next
    stage's cache key) and is published as the stage's artifact."""
    if shards <= 1:
        (art,), states = _results([stage_task.submit(args=args, **fixed)], stage)
    else:
        parts, states = _results(stage_task.map(args=_shards(args, shards, out, stage, path_field),
                                                **{k: unmapped(v) for k, v in fixed.items()}), stage)
        (art,), merged = _results([merge_task.submit(shards=parts, out_dir=out, name=name)], "merge")
        states = states + merged
    runlog.publish_dataset(stage, art, shards)
    return art, states


def _collect(task_id, episodes, num_envs, seed, device, out, shards, *, cameras=PIPELINE_CAMERAS, task_options=None,
             max_steps=None):
    args = CollectArgs(task=task_id, episodes=episodes, num_envs=num_envs, seed=seed, device=device, randomize=True,
                       dataset_path=str(Path(out) / "demos.hdf5"), cameras=cameras,
                       task_options=dict(task_options or {}), **({"max_steps": max_steps} if max_steps else {}))
    return _run_dataset_stage(collect_task, args, shards=shards, out=out, stage="collect", name="demos",
                              path_field="dataset_path")


def _mimic(source, episodes, num_envs, seed, device, out, shards):
    args = MimicArgs(dataset_path=source["path"], output_path=str(Path(out) / "mimic.hdf5"), episodes=episodes,
                     num_envs=num_envs, seed=seed, device=device, cameras=PIPELINE_CAMERAS)
    return _run_dataset_stage(mimic_task, args, shards=shards, out=out, stage="mimic", name="mimic",
                              path_field="output_path", source=source)


def _train(dataset, train_cfg, out, gpus=1):
    (ckpt,), states = _results([train_task.submit(dataset=dataset, train_cfg=dict(train_cfg or {}), out_dir=out,
                                                  gpus=gpus)], "train")
    runlog.publish_loss_curve(ckpt)
    return ckpt, states


def _evaluate(checkpoint, task_id, episodes, num_envs, seed, device, shards, max_steps, recording=None, *,
              cameras=PIPELINE_CAMERAS, task_options=None, phase_checkpoints=None):
    """Evaluate a checkpoint artifact, or a coherent task's ``phase_checkpoints`` (phase -> artifact; checkpoint
    None), in ``shards`` runs with disjoint seeds; the summed metrics (per phase too) and the task states."""
    args = EvaluateArgs(task=task_id, checkpoint=None if checkpoint is None else checkpoint["path"], episodes=episodes,
                        num_envs=num_envs, seed=seed, device=device, randomize=True, max_steps=max_steps,
                        cameras=cameras, task_options=dict(task_options or {}))
    shard_args = _shards(args, shards)
    if recording is not None:  # two episodes of the first shard, for the viewer
        shard_args[0] = replace(shard_args[0], rerun_save=str(recording), rerun_worlds=EVAL_RECORDED_EPISODES)
    parts, states = _results(evaluate_task.map(checkpoint=unmapped(checkpoint), args=shard_args,
                                               phase_checkpoints=unmapped(phase_checkpoints)), "evaluate")
    n = sum(p["episodes"] for p in parts)
    ok = sum(p["successes"] for p in parts)
    metrics = {"episodes": n, "successes": ok, "success_rate": ok / max(n, 1),
               "termination_reasons": _summed(p["termination_reasons"] for p in parts),
               "subtask_signals": _summed(p.get("subtask_signals", {}) for p in parts),
               "phases": {name: {"reached": sum(p["phases"][name]["reached"] for p in parts),
                                 "passed": sum(p["phases"][name]["passed"] for p in parts),
                                 "stalled": _summed(p["phases"][name]["stalled"] for p in parts)}
                          for name in parts[0]["phases"]},
               "average_length": sum(p["average_length"] * p["episodes"] for p in parts) / max(n, 1)}
    recorded = [p["recording"] for p in parts if p.get("recording")]
    if recorded:
        metrics["recording"] = recorded[0]
    runlog.publish_evaluation(metrics)
    return metrics, states


def _summed(counts) -> dict[str, int]:
    """Counters (name -> count) added up."""
    out: dict[str, int] = {}
    for c in counts:
        for k, v in c.items():
            out[k] = out.get(k, 0) + v
    return out


@flow(name="collect")
def collect(task_id: str, episodes: int = 4, num_envs: int = 2, seed: int = 0, device: str | None = None,
            out: str = "outputs/pipeline", shards: int = 1) -> tuple[dict[str, Any], list[str]]:
    """Expert demos of ``task_id`` (randomised) -> (dataset artifact, task states); ``shards`` > 1: disjoint
    seeds, merged."""
    return _collect(task_id, episodes, num_envs, seed, device, out, shards)


@flow(name="mimic")
def mimic(source: dict[str, Any], episodes: int = 40, num_envs: int = 4, seed: int = 1, device: str | None = None,
          out: str = "outputs/pipeline", shards: int = 1) -> tuple[dict[str, Any], list[str]]:
    """Mimic expansion of a dataset artifact -> (dataset artifact, task states)."""
    return _mimic(source, episodes, num_envs, seed, device, out, shards)


@flow(name="train")
def train(dataset: dict[str, Any], train_cfg: dict[str, Any] | None = None,
          out: str = "outputs/pipeline") -> tuple[dict[str, Any], list[str]]:
    """Diffusion policy on a dataset artifact -> (checkpoint artifact, task states)."""
    return _train(dataset, train_cfg, out)


@flow(name="evaluate")
def evaluate(checkpoint: dict[str, Any], task_id: str, episodes: int = 10, num_envs: int = 5, seed: int = 10_000,
             device: str | None = None, shards: int = 1, max_steps: int = 600) -> tuple[dict[str, Any], list[str]]:
    """Success rate of a checkpoint artifact (randomised; ``shards`` > 1: disjoint seeds, summed) -> (metrics,
    task states)."""
    return _evaluate(checkpoint, task_id, episodes, num_envs, seed, device, shards, max_steps)


@flow(name="pipeline")
def pipeline(task_id: str = _P.task, demos: int = _R["demos"], mimic_episodes: int = _R["mimic_episodes"],
             train_cfg: dict[str, Any] | None = None, eval_episodes: int = _R["eval_episodes"],
             num_envs: int = _R["num_envs"], device: str | None = _P.device, out: str = _P.out, seed: int = _P.seed,
             workers: int = _P.workers, eval_max_steps: int = 600, gpus: int = 1) -> dict[str, Any]:
    """collect -> mimic -> train -> evaluate for ``task_id``, each stage a task run of this flow (one task
    runner for all); publishes one artifact per stage and a markdown summary (``runlog``) and writes
    ``<out>/metrics.json``. ``workers`` > 1 shards collection, Mimic and evaluation.
    Defaults are ``PipelineArgs``'s (``newton-lab pipeline``); ``train_cfg`` None is the policy's default."""
    runlog.quiet_console(INPUT_ERRORS)
    log = get_run_logger()
    out_dir = output_path(Path(out) / "metrics.json").parent
    demo_art, s_collect = _collect(task_id, demos, num_envs, seed, device, out, workers)
    log.info("collect: %s", "/".join(s_collect))
    gen_art, s_mimic = _mimic(demo_art, mimic_episodes, num_envs, seed + 1, device, out, workers)
    log.info("mimic: %s", "/".join(s_mimic))
    ckpt_art, s_train = _train(gen_art, train_cfg, out, gpus)
    log.info("train: %s", "/".join(s_train))
    metrics, s_eval = _evaluate(ckpt_art, task_id, eval_episodes, num_envs, seed + 10_000, device, workers,
                                eval_max_steps, recording=Path(out) / "evaluation.rrd")
    log.info("evaluate: %s; success rate %.1f%% over %d episodes", "/".join(s_eval), 100 * metrics["success_rate"],
             metrics["episodes"])
    summary = {"task": task_id, "success_rate": metrics["success_rate"], "evaluation": metrics,
               "artifacts": {"demos": demo_art, "mimic": gen_art, "checkpoint": ckpt_art},
               "stage_states": {"collect": s_collect, "mimic": s_mimic, "train": s_train, "evaluate": s_eval}}
    (out_dir / "metrics.json").write_text(json.dumps(summary, indent=1))
    runlog.publish_summary(task_id, demo_art, gen_art, ckpt_art, metrics, out_dir)
    return summary


def run_pipeline(*, runner: str = _P.runner, workers: int = _P.workers, address: str | None = _P.address,
                 retries: int = _P.retries, **kwargs) -> dict[str, Any]:
    """Run ``pipeline`` with the chosen task runner: ``local`` (threads in this process) or ``dask``
    (a local cluster of ``workers`` processes, or the scheduler at ``address``). ``PipelineArgs.pipeline_kwargs()``
    gives every keyword from the command line's arguments."""
    _check(kwargs.get("task_id", _P.task), runner, workers)
    _check_counts(**{k: kwargs.get(k) for k in ("demos", "mimic_episodes", "eval_episodes", "num_envs",
                                                 "eval_max_steps", "gpus")})
    from .long_horizon import has_phases, long_horizon_pipeline  # deferred: it imports this module

    flow_fn = pipeline
    if has_phases(kwargs.get("task_id", _P.task)):
        if kwargs.pop("mimic_episodes", None) is not None:
            raise ValueError("a coherent task's pipeline takes more coherent demos (--demos) instead of Mimic; "
                             "drop --mimic-episodes")
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
    runlog.quiet_console(INPUT_ERRORS)
    return flow_fn.with_options(**options)(workers=workers if runner == "dask" else 1, **kwargs)


def _check_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Fail within ``timeout_s`` with a one-line error when the Dask scheduler is unreachable."""
    u = urlparse(address if "://" in address else f"tcp://{address}")
    try:
        socket.create_connection((u.hostname, u.port or 8786), timeout=timeout_s).close()
    except OSError as exc:
        raise ConnectionError(f"Dask scheduler {address} is unreachable ({exc}); start it or drop --address") from None
