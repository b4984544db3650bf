"""Prefect flows: ``collect``, ``mimic``, ``train``, ``evaluate`` and ``pipeline`` chaining them.

Each stage is a Prefect task over artifacts (path + content hash) cached on its inputs, so a re-run of
the same pipeline is answered from the cache (task state ``Cached``) and a failed stage is retried alone.
With ``runner="dask"``, collection, Mimic and evaluation are split into shards with disjoint seed ranges,
mapped over a Dask cluster (a local one, or the scheduler ``address`` given), and shard datasets are
merged into one.
"""

from __future__ import annotations

import json
import socket
from dataclasses import replace
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from prefect import flow, task, unmapped
from prefect.artifacts import create_markdown_artifact
from prefect.cache_policies import INPUTS

from ..commands import CollectArgs, EvaluateArgs, MimicArgs, PipelineArgs
from ..task_api.registry import lookup
from . import stages
from .artifacts import artifact
from .settings import check_api_reachable

SEED_STRIDE = 100_000
"""Seed distance between shards: each shard draws from its own seed range."""

VALID_RUNNERS = ("local", "dask")

_P = PipelineArgs()
"""The pipeline's defaults: the ones of ``newton-lab pipeline``."""


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
    return task(fn, name=name, cache_policy=INPUTS, persist_result=True, retries=1, retry_delay_seconds=1,
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
    return artifact(path, "dataset", episodes=ref["episodes"],
                    **{k: sum(s["metrics"].get(k, 0) for s in shards) for k in ("attempts", "successes")})


def _with_state(state, shard_states: list[str] | None = None):
    """(artifact, task state names): the artifact goes downstream unchanged (it is the next stage's cache
    key); the state names ("Completed", "Cached", ...) are reported by the pipeline."""
    return state.result(), [*(shard_states or []), state.name]


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


def _sharded(task, args, *, shards: int, out: str, stage: str, name: str, path_field: str, **fixed) -> dict[str, Any]:
    """Map ``task`` over the shards of ``args`` and merge the shard datasets into ``<out>/<name>.hdf5``;
    returns the merged artifact with the shard states."""
    futures = task.map(args=_shards(args, shards, out, stage, path_field), **{k: unmapped(v) for k, v in fixed.items()})
    return _with_state(merge_task(shards=[f.result() for f in futures], out_dir=out, name=name,
                                  return_state=True), [f.state.name for f in futures])


@flow(name="collect")
def collect(task_id: str, episodes: int = 4, num_envs: int = 2, seed: int = 0, device: str | None = None,
            out: str = "outputs/pipeline", shards: int = 1) -> dict[str, Any]:
    """Expert demos of ``task_id`` (randomised) -> dataset artifact (``shards`` > 1: disjoint seeds, merged)."""
    args = CollectArgs(task=task_id, episodes=episodes, num_envs=num_envs, seed=seed, device=device, randomize=True,
                       dataset_path=str(Path(out) / "demos.hdf5"))
    if shards <= 1:
        return _with_state(collect_task(args=args, return_state=True))
    return _sharded(collect_task, args, shards=shards, out=out, stage="collect", name="demos",
                    path_field="dataset_path")


@flow(name="mimic")
def mimic(source: dict[str, Any], episodes: int = 40, num_envs: int = 4, seed: int = 1, device: str | None = None,
          out: str = "outputs/pipeline", shards: int = 1) -> dict[str, Any]:
    """Mimic expansion of a dataset artifact -> dataset artifact."""
    args = MimicArgs(dataset_path=source["path"], output_path=str(Path(out) / "mimic.hdf5"), episodes=episodes,
                     num_envs=num_envs, seed=seed, device=device)
    if shards <= 1:
        return _with_state(mimic_task(source=source, args=args, return_state=True))
    return _sharded(mimic_task, args, shards=shards, out=out, stage="mimic", name="mimic", path_field="output_path",
                    source=source)


@flow(name="train")
def train(dataset: dict[str, Any], train_cfg: dict[str, Any] | None = None, out: str = "outputs/pipeline") -> dict[str, Any]:
    """Diffusion policy on a dataset artifact -> checkpoint artifact."""
    return _with_state(train_task(dataset=dataset, train_cfg=dict(train_cfg or {}), out_dir=out, return_state=True))


@flow(name="evaluate")
def evaluate(checkpoint: dict[str, Any], task_id: str, episodes: int = 10, num_envs: int = 5, seed: int = 10_000,
             device: str | None = None, shards: int = 1, max_steps: int = 600) -> dict[str, Any]:
    """Success rate of a checkpoint artifact (randomised; ``shards`` > 1: disjoint seeds, summed)."""
    args = EvaluateArgs(task=task_id, checkpoint=checkpoint["path"], episodes=episodes, num_envs=num_envs, seed=seed,
                        device=device, randomize=True, max_steps=max_steps)
    futures = evaluate_task.map(checkpoint=unmapped(checkpoint), args=_shards(args, shards))
    parts = [f.result() for f in futures]
    states = [f.state.name for f in futures]
    n = sum(p["episodes"] for p in parts)
    ok = sum(p["successes"] for p in parts)
    reasons: dict[str, int] = {}
    signals: dict[str, int] = {}
    for p in parts:
        for k, v in p["termination_reasons"].items():
            reasons[k] = reasons.get(k, 0) + v
        for k, v in p.get("subtask_signals", {}).items():
            signals[k] = signals.get(k, 0) + v
    return {"episodes": n, "successes": ok, "success_rate": ok / max(n, 1), "termination_reasons": reasons,
            "subtask_signals": signals,
            "average_length": sum(p["average_length"] * p["episodes"] for p in parts) / max(n, 1)}, states


def _markdown(task_id: str, demos, gen, ckpt, metrics, out: Path) -> str:
    rows = [
        ("expert demos", f"{demos['metrics'].get('episodes')} ({demos['metrics'].get('success_rate', 1.0):.0%} success)"),
        ("mimic demos", f"{gen['metrics'].get('episodes')} (generation rate "
                        f"{gen['metrics'].get('generation_success_rate', gen['metrics'].get('successes', 0) / max(gen['metrics'].get('attempts', 1), 1)):.0%})"),
        ("final training loss", f"{ckpt['metrics'].get('final_loss')}"),
        ("evaluation success rate", f"{metrics['success_rate']:.1%} of {metrics['episodes']} episodes"),
    ]
    table = "\n".join(f"| {k} | {v} |" for k, v in rows)
    paths = "\n".join(f"- {k}: `{a['path']}` (sha256 {a['sha256'][:12]})" for k, a in
                      (("demos", demos), ("mimic", gen), ("checkpoint", ckpt)))
    return f"# newton_lab pipeline: {task_id}\n\n| metric | value |\n|---|---|\n{table}\n\n{paths}\n- metrics: `{out / 'metrics.json'}`\n"


@flow(name="pipeline")
def pipeline(task_id: str = _P.task, demos: int = _P.demos, mimic_episodes: int = _P.mimic_episodes,
             train_cfg: dict[str, Any] | None = None, eval_episodes: int = _P.eval_episodes,
             num_envs: int = _P.num_envs, device: str | None = _P.device, out: str = _P.out, seed: int = _P.seed,
             workers: int = _P.workers, eval_max_steps: int = 600) -> dict[str, Any]:
    """collect -> mimic -> train -> evaluate for ``task_id``; publishes a markdown artifact with the metrics
    table and writes ``<out>/metrics.json``. ``workers`` > 1 shards collection, Mimic and evaluation.
    Defaults are ``PipelineArgs``'s (``newton-lab pipeline``); ``train_cfg`` None is the policy's default."""
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    demo_art, s_collect = collect(task_id, episodes=demos, num_envs=num_envs, seed=seed, device=device, out=out,
                                  shards=workers)
    gen_art, s_mimic = mimic(demo_art, episodes=mimic_episodes, num_envs=num_envs, seed=seed + 1, device=device,
                             out=out, shards=workers)
    ckpt_art, s_train = train(gen_art, train_cfg=train_cfg, out=out)
    metrics, s_eval = evaluate(ckpt_art, task_id, episodes=eval_episodes, num_envs=num_envs, seed=seed + 10_000,
                               device=device, shards=workers, max_steps=eval_max_steps)
    summary = {"task": task_id, "success_rate": metrics["success_rate"], "evaluation": metrics,
               "artifacts": {"demos": demo_art, "mimic": gen_art, "checkpoint": ckpt_art},
               "stage_states": {"collect": s_collect, "mimic": s_mimic, "train": s_train, "evaluate": s_eval}}
    (out_dir / "metrics.json").write_text(json.dumps(summary, indent=1))
    create_markdown_artifact(markdown=_markdown(task_id, demo_art, gen_art, ckpt_art, metrics, out_dir),
                             key="newton-lab-pipeline", description=f"newton_lab pipeline metrics for {task_id}")
    return summary


def run_pipeline(*, runner: str = _P.runner, workers: int = _P.workers, address: str | None = _P.address,
                 retries: int = _P.retries, **kwargs) -> dict[str, Any]:
    """Run ``pipeline`` with the chosen task runner: ``local`` (threads in this process) or ``dask``
    (a local cluster of ``workers`` processes, or the scheduler at ``address``). ``PipelineArgs.pipeline_kwargs()``
    gives every keyword from the command line's arguments."""
    _check(kwargs.get("task_id", _P.task), runner, workers)
    _check_counts(**{k: kwargs.get(k) for k in ("demos", "mimic_episodes", "eval_episodes", "num_envs",
                                                 "eval_max_steps")})
    check_api_reachable()
    options: dict[str, Any] = {}
    if runner == "dask":
        from prefect_dask import DaskTaskRunner  # deferred: Dask is slow to import and only the dask runner needs it

        if address:
            _check_scheduler(address)
            options["task_runner"] = DaskTaskRunner(address=address)
        else:
            options["task_runner"] = DaskTaskRunner(cluster_kwargs={
                "n_workers": workers, "processes": True, "threads_per_worker": 1, "dashboard_address": None})
    for t in (collect_task, mimic_task, train_task, evaluate_task):
        t.retries = retries
    return pipeline.with_options(**options)(workers=workers if runner == "dask" else 1, **kwargs)


def _check_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Fail within ``timeout_s`` with a one-line error when the Dask scheduler is unreachable."""
    u = urlparse(address if "://" in address else f"tcp://{address}")
    try:
        socket.create_connection((u.hostname, u.port or 8786), timeout=timeout_s).close()
    except OSError as exc:
        raise ConnectionError(f"Dask scheduler {address} is unreachable ({exc}); start it or drop --address") from None
