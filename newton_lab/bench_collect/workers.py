"""``bench_collect_on_workers``: ``bench_collect`` on several Dask worker processes at once (one per GPU), their
timed runs lined up by a start gate, with an optional lone baseline before and after."""

from __future__ import annotations

import dataclasses
import functools
import uuid
from pathlib import Path
from typing import Any

from ..flows.cluster import cluster_options, pins_gpus, quiet_shutdown, visible_gpus
from .single import bench_collect
from .timing import ZARR_WRITER_PARTS


def bench_collect_on_workers(
    task_id: str,
    *,
    workers: int,
    num_envs: int = 4,
    episodes: int = 16,
    device: str | None = None,
    dataset_path: str | Path = "outputs/bench_collect.zarr",
    max_steps: int = 1000,
    baseline: bool = False,
    writer: str = "auto",
    cameras: bool | dict = False,
    task_options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """``bench_collect`` on ``workers`` Dask worker processes at once, the way ``--runner dask`` shards collection:
    one worker per GPU on a CUDA host when ``device`` is None or ``"cuda"`` (each sees only its GPU), else
    processes on ``device``. Worker ``i`` collects its share of ``episodes`` with seed ``i`` into its own shard
    ``<stem>_w<i><suffix>`` (no prefilled run). The aggregate rate is every worker's successful demos over the
    span from the first timed run's start to the last one's end, so workers that did not overlap are not
    counted as parallel; the timed runs start together (each worker waits at a gate after its first use, which
    takes longer on the worker that compiles). With ``baseline`` worker 0 also collects one worker's share alone, once
    before the workers' run (``<stem>_alone<suffix>``) and once after it (``<stem>_alone2<suffix>``; same cluster,
    same demos per GPU), and ``scaling`` is the aggregate demos/s over the mean of the two lone rates: a shared
    disk or a busy host drifts within a lease, and bracketing the parallel run cancels a linear drift."""
    from distributed import Client, LocalCluster  # deferred: Dask is slow to import

    if workers < 1 or episodes < workers:
        raise ValueError(f"--workers {workers} with --episodes {episodes}: give 1 <= workers <= episodes")
    gpus = visible_gpus() if pins_gpus(device) else []
    if gpus and len(gpus) < workers:
        raise ValueError(
            f"--workers {workers} needs {workers} GPUs, this host shows {len(gpus)}; "
            f"use --workers {len(gpus)} or a --device to share"
        )
    path = Path(dataset_path)
    shards, alone = _fresh_paths(path, workers, baseline)
    opts = cluster_options(workers, device, gpus=gpus)
    quiet_shutdown()
    run = functools.partial(
        bench_collect,
        task_id,
        num_envs=num_envs,
        device="cuda" if gpus else device,
        prefill=0,
        max_steps=max_steps,
        writer=writer,
        cameras=cameras,
        task_options=task_options,
    )
    with opts.get("cluster_class", LocalCluster)(**opts["cluster_kwargs"]) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        # one task per worker, by name (a restarted worker keeps it): two gated runs on one worker would wait forever
        names = sorted((w["name"] for w in client.scheduler_info()["workers"].values()), key=str)

        def alone_run(shard: Path) -> dict[str, Any]:  # worker 0 alone (its GPU, its process), one worker's share
            return client.submit(
                run,
                episodes=episodes // workers,
                dataset_path=str(shard),
                seed=0,
                pure=False,
                workers=[names[0]],
                allow_other_workers=False,
            ).result()

        lone = [alone_run(alone[0])] if baseline else []
        parts = _gated_runs(client, run, names, shards, episodes)
        lone += [alone_run(alone[1])] if baseline else []
    return _aggregate(task_id, workers, num_envs, episodes, path, parts, shards, lone, alone)


def _gated_runs(client, run, names: list, shards: list[Path], episodes: int) -> list[dict[str, Any]]:
    """Worker ``i`` collects its share of ``episodes`` into ``shards[i]`` with seed ``i``; the timed runs start together
    (a start gate after each worker's first use)."""
    workers = len(shards)
    gate = f"bench-collect-{uuid.uuid4().hex}"
    futures = [
        client.submit(
            run,
            episodes=episodes // workers + (i < episodes % workers),
            dataset_path=str(shard),
            seed=i,
            start_gate=_StartGate(gate, i),
            pure=False,
            workers=[names[i]],
            allow_other_workers=False,
        )
        for i, shard in enumerate(shards)
    ]
    _open_gate(client, gate, futures)
    return client.gather(futures)


def _fresh_paths(path: Path, workers: int, baseline: bool) -> tuple[list[Path], list[Path]]:
    """The workers' shards ``<stem>_w<i><suffix>`` and the baseline's two lone datasets; refused if any of them (or
    its warm-up dataset) exists."""
    shards = [path.with_name(f"{path.stem}_w{i}{path.suffix}") for i in range(workers)]
    alone = [path.with_name(f"{path.stem}_alone{n}{path.suffix}") for n in ("", "2")] if baseline else []
    written = shards + alone
    for p in written + [s.with_name(f"{s.stem}_warmup{s.suffix}") for s in written]:
        if p.exists():
            raise FileExistsError(f"{p} exists; bench-collect writes fresh shards (choose a new --dataset-path)")
    return shards, alone


def _aggregate(task_id, workers, num_envs, episodes, path: Path, parts, shards, lone, alone) -> dict[str, Any]:
    """The workers' results as one: every worker's successful demos over the span of their timed runs, each worker's
    figures, and the scaling over the lone baseline's mean rate."""
    ok = sum(p["successful_demos"] for p in parts)
    span = max(p["ended_at"] for p in parts) - min(p["started_at"] for p in parts)
    keep = (
        "device",
        "device_name",
        "successful_demos",
        "wall_s",
        "demos_per_hour",
        "first_use_s",
        "physics_s",
        "agent_s",
        "loop_s",
        "writer_s",
        *ZARR_WRITER_PARTS,
        "presync_s",
        "writer_batches",
        "bytes_per_demo",
        "inodes_per_demo",
        "gpu",
        "ready_at",
        "started_at",
    )
    return {
        "task": task_id,
        "workers": workers,
        "num_envs": num_envs,
        "episodes": episodes,
        "device_names": [p["device_name"] for p in parts],
        "format": path.suffix,
        "successful_demos": ok,
        "wall_s": span,
        "demos_per_s": ok / span,
        "demos_per_hour": 3600 * ok / span,
        "first_use_s": max(p["first_use_s"] for p in parts),
        "start_skew_s": max(p["started_at"] for p in parts) - min(p["started_at"] for p in parts),
        "per_worker": [{k: p[k] for k in keep if k in p} | {"dataset_path": str(s)} for p, s in zip(parts, shards)],
        **(
            {}
            if not lone
            else {
                "scaling": ok / span / (sum(r["demos_per_s"] for r in lone) / len(lone)),
                "baseline": [
                    {k: r[k] for k in (*keep, "demos_per_s") if k in r} | {"dataset_path": str(a)}
                    for r, a in zip(lone, alone)
                ],
            }
        ),
    }


GATE_TIMEOUT_S = 3600.0
"""How long a worker waits at the start gate for the others (their first use: compiling, loading kernels)."""


@dataclasses.dataclass(frozen=True)
class _StartGate:
    """Worker ``index``'s side of a start gate: announce readiness (its first use is done), wait for the go."""

    key: str
    index: int

    def __call__(self) -> None:
        from distributed import Event  # deferred: Dask is slow to import

        Event(f"{self.key}-ready-{self.index}").set()
        if not Event(f"{self.key}-go").wait(GATE_TIMEOUT_S):
            raise TimeoutError(f"bench-collect worker {self.index} waited {GATE_TIMEOUT_S:.0f} s for the others")


def _open_gate(client, key: str, futures: list) -> None:
    """Open the start gate once every worker is ready; returns early if a worker failed (gather raises its error)."""
    from distributed import Event  # deferred: Dask is slow to import

    for i in range(len(futures)):
        ready = Event(f"{key}-ready-{i}", client=client)
        while not ready.wait(0.5):
            if any(f.status in ("error", "cancelled") for f in futures):
                return
    Event(f"{key}-go", client=client).set()
