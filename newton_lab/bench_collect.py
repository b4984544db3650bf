"""Expert collection throughput (``newton-lab bench-collect``): successful demos/s and per GPU-hour, the seconds split
into the three stages (physics ``env.step``, agent ``agent.act``, writer: the background thread's batch writes) and
the loop's hand-over and final drain, one process or several Dask workers at once (``bench_collect_on_workers``).
``summary`` words a result for the terminal: the stages per vector step and whether physics bounds the run."""

from __future__ import annotations

import dataclasses
import functools
import os
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch
import warp as wp
from torch.profiler import ProfilerActivity, profile, record_function, schedule

from .datasets import list_demos, open_writer, read_episode
from .datasets.files.durability import sync_tree
from .datasets.files.output_paths import output_path
from .datasets.zarr import store as zarr_store
from .envs import make_env
from .envs.rollout import Timers, env_args
from .flows.cluster import cluster_options, pins_gpus, quiet_shutdown, visible_gpus


class _Clock:
    """Seconds spent inside wrapped calls; each call waits for the device so queued work is charged to it."""

    def __init__(self, device) -> None:
        self.device, self.seconds = device, 0.0

    def wrap(self, fn):
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            out = fn(*args, **kwargs)
            wp.synchronize_device(self.device)
            self.seconds += time.perf_counter() - t0
            return out

        return timed


class _DeviceClock:
    """Seconds the device spends on wrapped calls, from CUDA events around them, read at the end: no host wait, so a
    step launched asynchronously stays so and the host work that overlaps it is not charged to it. On the CPU, where
    every call is synchronous, a ``_Clock``."""

    def __init__(self, device) -> None:
        self.device, self._events, self._host = device, [], _Clock(device)

    def wrap(self, fn):
        if not self.device.is_cuda:
            return self._host.wrap(fn)

        def timed(*args, **kwargs):
            start, end = wp.Event(self.device, enable_timing=True), wp.Event(self.device, enable_timing=True)
            self.device.stream.record_event(start)  # the env's device's stream, where its step runs
            out = fn(*args, **kwargs)
            self.device.stream.record_event(end)
            self._events.append((start, end))
            return out

        return timed

    @property
    def seconds(self) -> float:
        if not self.device.is_cuda:
            return self._host.seconds
        wp.synchronize_device(self.device)
        return sum(wp.get_event_elapsed_time(a, b) for a, b in self._events) / 1e3


TRACE_AFTER_STEPS = 300
"""Vector steps of the timed run before ``--trace`` records, by default: past the first episodes' ends (PickCube's
come after ~150 steps at 4096 rows). The rows start together and their episodes keep ending in bursts, so a
window may catch few ends (on an H200, steps 300-320 of PickCube held few): move it with ``--trace-after``."""
TRACE_STEPS = 20
"""Vector steps ``--trace`` records (a 4096-row PickCube step is ~10 MB of trace with the Python tracer on)."""


class _Trace:
    """A ``torch.profiler`` window over ``TRACE_STEPS`` vector steps of the timed run (CPU ops, the Python tracer, and
    on a GPU every kernel and copy of the process, Warp's too, through CUPTI), each stage a labelled range: saved as
    a Chrome trace (``path``, ``.json.gz``: Perfetto opens it) and a table of the costliest operations
    (``<path>.txt``). What a GPU timeline shows and the stage clocks cannot: which host call waits for which kernel."""

    def __init__(self, path: Path, device, after: int = TRACE_AFTER_STEPS) -> None:
        self.path, self.after = path, after
        self.cuda = device.is_cuda
        acts = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if self.cuda else [])
        self.prof = profile(
            activities=acts,
            with_stack=True,
            on_trace_ready=self._save,
            schedule=schedule(wait=after, warmup=2, active=TRACE_STEPS, repeat=1),
        )

    def wrap(self, label: str, fn):
        def labelled(*args, **kwargs):
            with record_function(label):
                return fn(*args, **kwargs)

        return labelled

    def stepping(self, fn):
        """``fn`` (the env step) that moves the trace's window on by one step after each call."""

        def stepped(*args, **kwargs):
            out = fn(*args, **kwargs)
            self.prof.step()
            return out

        return stepped

    def _save(self, prof) -> None:
        prof.export_chrome_trace(str(self.path))
        tables = [f"# {self.path.name}: {TRACE_STEPS} vector steps after {self.after}"]
        keys = (("self_cuda_time_total", "self_device_time_total") if self.cuda else ()) + (
            "cpu_time_total",
            "self_cpu_time_total",
        )
        averages = prof.key_averages()
        for key in keys:
            try:
                tables += [f"\n## by {key}", averages.table(sort_by=key, row_limit=40, max_name_column_width=70)]
            except (AttributeError, KeyError, ValueError):  # the CUDA column's name differs across torch versions
                continue
        Path(f"{self.path}.txt").write_text("\n".join(tables) + "\n")


ZARR_WRITER_PARTS = {"writer_files_s": "files", "writer_sync_s": "sync"}
"""A zarr batch's seconds split (``zarr.store.BATCH_SECONDS``): encoding and writing its demos' files (writer
processes or threads), and the one ``syncfs`` that makes them durable (disk-bound where the files are many); the
rest of ``writer_s`` is the lock, the renames and the commit."""


def _collect_timed(
    env,
    agent,
    episodes: int,
    path: Path,
    max_steps: int,
    trace: Path | None = None,
    trace_after: int = TRACE_AFTER_STEPS,
    writer: str = "auto",
) -> dict[str, Any]:
    """One ``env.collect`` with physics (``env.step``: the device's time, ``_DeviceClock``), agent (``agent.act``) and
    writer (the background thread's ``append_prepared`` calls, or those the writer process reports, split as
    ``ZARR_WRITER_PARTS`` says for zarr) seconds measured (the rollout's ``Timers``); the loop's own time is the rest
    (``loop_s``), of which ``hand_over_s`` passes ended episodes to the writer (gather, checks, the copy off the
    device, queueing) and ``drain_s`` waits for the writer after the last step. ``physics_share`` (physics over wall)
    near 1 means the device's step bounds the loop; the rest of the wall is the host's own work."""
    physics, acting, writing = _DeviceClock(env.device), _Clock(env.device), _Clock("cpu")
    handing, draining = _Clock("cpu"), _Clock("cpu")
    clocks = {"physics": physics, "agent": acting, "writer": writing, "hand-over": handing, "drain": draining}
    tracer = _Trace(trace, env.device, trace_after) if trace is not None else None

    def timer(name: str):
        if tracer is None:
            return clocks[name].wrap
        if name == "physics":  # each env step also moves the trace's window on
            return lambda fn: tracer.stepping(tracer.wrap(name, clocks[name].wrap(fn)))
        return lambda fn: tracer.wrap(name, clocks[name].wrap(fn))

    timers = Timers(
        step=timer("physics"),
        act=timer("agent"),
        write=timer("writer"),
        hand_over=timer("hand-over"),
        drain=timer("drain"),
    )
    store_before = dict(zarr_store.BATCH_SECONDS)
    if tracer is not None:
        tracer.prof.start()
    t0 = time.perf_counter()
    try:
        ref = env.collect(
            agent=agent,
            episodes=episodes,
            path=path,
            max_steps=max_steps,
            progress=False,
            only_successes=True,
            max_attempts=2 * episodes,
            timers=timers,
            writer=writer,
        )
    finally:
        wall = time.perf_counter() - t0
        if tracer is not None:
            tracer.prof.stop()
    ok = ref.metadata["successes"]
    spent = ref.metadata.get("writer_seconds")  # a writer process's own clock (its process's zarr split)
    split = (
        {
            name: (spent[part] if spent else zarr_store.BATCH_SECONDS[part] - store_before[part])
            for name, part in ZARR_WRITER_PARTS.items()
        }
        if path.suffix == ".zarr"
        else {}
    )
    writer_s = spent["write"] if spent else writing.seconds
    return {
        "successful_demos": ok,
        "attempts": ref.metadata["attempts"],
        "wall_s": wall,
        "demos_per_s": ok / wall,
        "demos_per_hour": 3600 * ok / wall,
        "physics_s": physics.seconds,
        "agent_s": acting.seconds,
        "writer_s": writer_s,
        **split,
        "writer": ref.metadata.get("writer"),
        "physics_share": physics.seconds / wall,
        "loop_s": wall - physics.seconds - acting.seconds,
        "hand_over_s": handing.seconds,
        "drain_s": draining.seconds,
        "vector_steps": ref.metadata.get("vector_steps"),
        "writer_batches": ref.metadata.get("writer_batches"),
    }


def bench_collect(
    task_id: str,
    *,
    num_envs: int = 4,
    episodes: int = 16,
    device: str | None = None,
    dataset_path: str | Path = "outputs/bench_collect.zarr",
    prefill: int = 10_000,
    max_steps: int = 1000,
    seed: int = 0,
    start_gate: Callable[[], None] | None = None,
    replan_batch: int | None = None,
    replan_wait: int | None = None,
    trace: str | Path | None = None,
    trace_after: int = TRACE_AFTER_STEPS,
    writer: str = "auto",
    cameras: bool | dict = False,
    task_options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Expert collection throughput (successful demos/s and per hour) with its seconds split into physics, agent
    and writer, bytes per stored demo, the first-use (compile) time measured apart, and the same run appending
    to a dataset that already holds ``prefill`` episodes (copies of the first demo, written in batches).
    ``started_at`` / ``ended_at`` (Unix seconds) bound the timed run, for ``bench_collect_on_workers``; one
    ``syncfs`` of the dataset's filesystem (``presync_s``) comes before it, and ``start_gate()``, when given, right
    after the first use (``bench_collect_on_workers`` lines the workers' timed runs up with it). ``replan_batch``,
    ``replan_wait``: the expert's ``PlannerAgent`` settings of those names (``None``: its defaults). ``trace``: a
    ``torch.profiler`` trace of ``TRACE_STEPS`` steps of the timed run to this path (``_Trace``), after ``trace_after``
    steps; the stage clocks of a traced run read high. ``writer``: ``collect``'s (``"auto"``, ``"thread"``,
    ``"process"``). ``cameras`` (``make_env``'s): the views rendered and recorded every step; their render and the
    frames' copy into the episode buffers are ``record_s`` (the loop's time besides the hand-over and the drain).
    ``task_options``: the task's options (e.g. ``obs_mode``)."""
    from .agents import expert_agent  # deferred: the agents import the planner's IK

    path = Path(dataset_path)
    if path.exists():
        raise FileExistsError(f"{path} exists; bench-collect writes a fresh dataset (choose a new --dataset-path)")
    output_path(path)
    t0 = time.perf_counter()
    env = make_env(
        task_id, num_envs=num_envs, device=device, seed=seed, randomize=True, cameras=cameras, task_options=task_options
    )
    agent = expert_agent(env)
    if (replan_batch, replan_wait) != (None, None) and not hasattr(agent, "replan_batch"):
        raise ValueError(
            f"--replan-batch / --replan-wait: the expert of {task_id} ({type(agent).__name__}) does not plan; drop them"
        )
    if replan_batch is not None:
        agent.replan_batch = replan_batch
    if replan_wait is not None:
        agent.replan_wait = replan_wait
    warm = path.with_name(f"{path.stem}_warmup{path.suffix}")  # first use: kernels, IK solver, writer
    _collect_timed(env, agent, 1, warm, max_steps, writer=writer)  # compiles the step, the IK solves, the writer path
    first_use = time.perf_counter() - t0
    out: dict[str, Any] = {
        "task": task_id,
        "device": str(env.device),
        "num_envs": num_envs,
        "episodes": episodes,
        "device_name": torch.cuda.get_device_name(env.device.ordinal) if env.device.is_cuda else "cpu",
        "first_use_s": first_use,
        "format": path.suffix,
        "gpu": os.environ.get("CUDA_VISIBLE_DEVICES"),
    }  # the host's GPU id behind a pinned cuda:0
    if start_gate is not None:
        out["ready_at"] = time.time()
        start_gate()
    t1 = time.perf_counter()
    sync_tree(path.parent)  # earlier writes (a deleted dataset's millions of files) are not charged to this run
    out["presync_s"] = time.perf_counter() - t1
    out["started_at"] = time.time()
    out.update(
        _collect_timed(
            env,
            agent,
            episodes,
            path,
            max_steps,
            trace=Path(trace) if trace else None,
            trace_after=trace_after,
            writer=writer,
        )
    )
    out["ended_at"] = time.time()
    size, inodes = _footprint(path)
    out["bytes_per_demo"] = size / max(out["successful_demos"], 1)
    out["inodes_per_demo"] = inodes / max(out["successful_demos"], 1)  # what a zarr dataset spends of an ext4 disk
    out["record_s"] = max(out["loop_s"] - out["hand_over_s"] - out["drain_s"], 0.0)  # render + frames per step
    out["cameras"] = {
        name: [spec.width, spec.height, list(spec.data)] for name, spec in env.sensors.camera_specs.items()
    }
    out["physics_s_per_step"] = out["physics_s"] / max(out["vector_steps"] or 1, 1)
    out["agent_plus_writer_s_per_step"] = (out["agent_s"] + out["writer_s"]) / max(out["vector_steps"] or 1, 1)
    out["physics_bound"] = out["agent_plus_writer_s_per_step"] <= out["physics_s_per_step"]
    if prefill > 0:
        demo = read_episode(warm, list_demos(warm)[0])
        full = path.with_name(f"{path.stem}_prefilled{path.suffix}")
        t1 = time.perf_counter()
        with open_writer(full, task_id=task_id, env_args=env_args(env)) as w:
            item = ({k: v for k, v in demo.items() if k != "attrs"}, True, None)
            for start in range(0, prefill, 512):
                w.append_episodes([item] * min(512, prefill - start))
        out["prefill_episodes"], out["prefill_s"] = prefill, time.perf_counter() - t1
        again = _collect_timed(env, agent, episodes, full, max_steps, writer=writer)
        out["prefilled_demos_per_s"] = again["demos_per_s"]
        out["prefilled_writer_s"] = again["writer_s"]
    return out


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
    shards = [path.with_name(f"{path.stem}_w{i}{path.suffix}") for i in range(workers)]
    alone = [path.with_name(f"{path.stem}_alone{n}{path.suffix}") for n in ("", "2")] if baseline else []
    written = shards + alone
    for p in written + [s.with_name(f"{s.stem}_warmup{s.suffix}") for s in written]:
        if p.exists():
            raise FileExistsError(f"{p} exists; bench-collect writes fresh shards (choose a new --dataset-path)")
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
        parts = client.gather(futures)
        lone += [alone_run(alone[1])] if baseline else []
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


def _footprint(path: Path) -> tuple[int, int]:
    """Bytes and inodes (files and folders) of a dataset file or folder."""
    if path.is_file():
        return path.stat().st_size, 1
    nodes = list(path.rglob("*"))
    return sum(p.stat().st_size for p in nodes if p.is_file()), len(nodes) + 1


def summary(out: dict[str, Any]) -> str:
    """``bench_collect``'s result in a few lines: demos/s and per GPU-hour, the three stages in seconds and per vector
    step, the rest of the loop, whether physics bounds the run (agent + writer per step <= physics per step) and the
    step's share of the wall time."""
    steps = max(out.get("vector_steps") or 1, 1)
    stage = {name: out[f"{name}_s"] for name in ("physics", "agent", "writer")}
    lines = [
        f"{out['task']} on {out['device_name']}, {out['num_envs']} envs, {out['format']}: "
        f"{out['successful_demos']} demos in {out['wall_s']:.1f} s = {out['demos_per_s']:.0f} demos/s = "
        f"{out['demos_per_hour'] / 1e6:.2f} M demos per GPU-hour",
        f"stages over {steps} vector steps: "
        + ", ".join(f"{name} {s:.2f} s ({1e3 * s / steps:.2f} ms/step)" for name, s in stage.items())
        + (
            f"; writer files {out['writer_files_s']:.2f} s, sync {out['writer_sync_s']:.2f} s"
            if "writer_files_s" in out
            else ""
        ),
        f"loop besides physics and agent {out['loop_s']:.2f} s: hand-over {out['hand_over_s']:.2f} s, "
        f"drain after the last step {out['drain_s']:.2f} s, render and frames {out.get('record_s', 0):.2f} s; "
        f"{out['bytes_per_demo'] / 1e3:.1f} KB and "
        f"{out['inodes_per_demo']:.2f} files per demo, {out['writer_batches']} writer batches "
        f"({out.get('writer') or 'BackgroundWriter'})",
        f"physics-bound (agent + writer <= physics per step): {'yes' if out['physics_bound'] else 'no'} "
        f"({1e3 * (stage['agent'] + stage['writer']) / steps:.2f} vs {1e3 * stage['physics'] / steps:.2f} "
        f"ms/step; the step is {100 * out['physics_share']:.0f} % of the wall); largest stage: "
        f"{max({**stage, 'render and frames': out.get('record_s', 0.0)}.items(), key=lambda kv: kv[1])[0]}",
    ]
    return "\n".join(lines)
