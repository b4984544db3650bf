"""Throughput of the full captured env step against the bare solver on the identical model.

Both are measured side by side in one process: the env's captured step (actions -> decimation solver
steps -> task kernel -> masked resets -> observations) and a graph of just ``decimation`` solver steps.
"""

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
from newton.sensors import SensorCamera

from .datasets import list_demos, open_writer, read_episode, zarr_store
from .datasets._common import sync_tree
from .datasets.outputs import output_path
from .envs import make_env
from .envs.rollout import Timers, env_args
from .flows.cluster import cluster_options, pins_gpus, quiet_shutdown, visible_gpus
from .policies.data import SequenceDataset
from .policies.diffusion import PRESETS, DiffusionPolicy, DiffusionPolicyConfig
from .policies.train_step import CudaGraphTrainStep, EagerTrainStep


def _time_graph(launch, steps: int, device) -> float:
    for _ in range(3):
        launch()
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(steps):
        launch()
    wp.synchronize_device(device)
    return (time.perf_counter() - t0) / steps


def bench(task_id: str, *, num_envs: int = 4, steps: int = 200, device: str | None = None,
          camera: str | None = None, resolution: tuple[int, int] = (128, 128),
          camera_data: tuple[str, ...] = ("rgb",)) -> dict[str, Any]:
    """Env-steps/s, bare world-steps/s and their per-step time ratio (env step / decimation solver steps).
    With ``camera``: also env-steps/s with that camera rendered every step (``resolution`` (w, h) [px],
    ``camera_data`` of rgb / depth / segmentation) against the camera ceiling measured beside it (``_ceiling``)."""
    cams = False if camera is None else {camera: {"resolution": tuple(resolution), "data": tuple(camera_data)}}
    env = make_env(task_id, num_envs=num_envs, device=device, seed=0, cameras=cams)
    step_graph = env.step_graph
    if step_graph is None:
        raise RuntimeError(f"step capture is unavailable on {env.device}; benchmark needs Warp graph capture")
    env.actions.copy_(env.current_action())
    with wp.ScopedDevice(env.device):
        with wp.ScopedCapture(device=env.device) as cap:
            env.simulate()
    bare_graph = cap.graph
    t_env = _time_graph(lambda: wp.capture_launch(step_graph), steps, env.device)
    t_bare = _time_graph(lambda: wp.capture_launch(bare_graph), steps, env.device)
    # the Python-facing step (validation + copy + launch) on the same env
    a = env.current_action()
    t_api = _time_graph(lambda: env.step(a), max(steps // 4, 1), env.device)
    dec = env.cfg.decimation
    out = {
        "task": task_id,
        "device": str(env.device),
        "device_name": torch.cuda.get_device_name() if env.device.is_cuda else "cpu",
        "num_envs": num_envs,
        "decimation": dec,
        "env_steps_per_s": num_envs / t_env,
        "env_steps_per_s_python_step": num_envs / t_api,
        "bare_world_steps_per_s": num_envs * dec / t_bare,
        "ratio_env_step_to_bare": t_env / t_bare,
    }
    if camera is not None:
        out.update(_camera_figures(env, camera, steps))
    return out


def _camera_figures(env, camera: str, steps: int) -> dict[str, Any]:
    """The env step plus its camera render (both captured, launched back to back, as ``env.step`` followed by
    reading ``env.images``) against the ceiling: the bare solver graph plus a bare ``SensorCamera`` render of one
    view per world at the same poses and resolution (BVH refit + render, captured)."""
    env.render()  # builds and captures the render graph
    cams = env.cameras
    render_graph = cams.render_graph
    if render_graph is None:
        raise RuntimeError(f"camera render capture is unavailable on {env.device}")
    spec = cams.specs[camera]
    with wp.ScopedDevice(env.device):
        sensor = SensorCamera(env.model)
        sensor.create_default_light(enable_shadows=False)
        rays = next(g.rays for g in cams.view_groups if camera in g.cameras)  # the env's pinhole rays
        n = env.num_envs
        color = sensor.allocate_image_color(n, spec.width, spec.height) if "rgb" in spec.data else None
        depth = sensor.allocate_image_depth(n, spec.width, spec.height) if "depth" in spec.data else None
        seg = sensor.allocate_image_shape_index(n, spec.width, spec.height) if "segmentation" in spec.data else None
        poses = wp.from_torch(cams.poses(camera).contiguous(), dtype=wp.transformf)

        def bare_render():
            env.model.bvh_refit_shapes(env.state)
            sensor.update(env.state, poses, rays, color_image=color, depth_image=depth, shape_index_image=seg)

        bare_render()  # compiles before the capture
        with wp.ScopedCapture(device=env.device) as cap:
            env.simulate()  # the bare solver steps (a graph launch inside a capture is CUDA-only)
            bare_render()
    ceiling_graph = cap.graph

    step_graph = env.step_graph

    def env_with_camera():
        wp.capture_launch(step_graph)
        wp.capture_launch(render_graph)

    t_cam = _time_graph(env_with_camera, steps, env.device)
    t_ceiling = _time_graph(lambda: wp.capture_launch(ceiling_graph), steps, env.device)
    mem = None
    if env.device.is_cuda:
        free, total = torch.cuda.mem_get_info(env.device.ordinal)
        mem = (total - free) / 2**20 / env.num_envs
    return {"camera": camera, "resolution": [spec.width, spec.height], "camera_data": list(spec.data),
            "env_steps_per_s_with_camera": env.num_envs / t_cam,
            "ceiling_env_steps_per_s": env.num_envs / t_ceiling,
            "ratio_camera_env_to_ceiling": t_ceiling / t_cam,
            "gpu_mem_used_mib_per_env": mem}


def bench_train(dataset: str, *, batch_size: int = 1024, steps: int = 200, device: str = "cpu",
                preset: str = "default", bf16: bool = False) -> dict[str, Any]:
    """Diffusion-policy optimiser steps/s on ``dataset``: the eager step and (on CUDA) the captured step, side by
    side in one process on fresh policies of the same architecture; with ``bf16`` each also under bfloat16
    autocast (keys ``..._bf16``)."""
    fields = {k: v for k, v in PRESETS[preset].items() if k not in ("batch_size", "max_steps", "epochs")}
    cfg = DiffusionPolicyConfig(**fields, batch_size=batch_size, device=device)
    data = SequenceDataset(dataset, pred_horizon=cfg.pred_horizon, obs_horizon=cfg.obs_horizon, obs_keys=cfg.obs_keys,
                           image_keys=cfg.image_keys)
    on_cuda = torch.device(device).type == "cuda"
    kinds = [EagerTrainStep] + ([CudaGraphTrainStep] if on_cuda else [])
    out: dict[str, Any] = {"dataset": dataset, "device": device, "batch_size": batch_size, "preset": preset,
                           "device_name": torch.cuda.get_device_name(device) if on_cuda else "cpu",
                           "windows": len(data), "image_keys": list(data.image_keys),
                           "image_shapes": {k: list(v) for k, v in data.image_shapes.items()}}
    for kind, precision in [(k, p) for p in ([False, True] if bf16 else [False]) for k in kinds]:
        torch.manual_seed(0)
        run_cfg = dataclasses.replace(cfg, bf16=precision)
        name = kind.__name__ + ("_bf16" if precision else "")
        policy = DiffusionPolicy.from_dataset(data, run_cfg).to(device)
        stepper, done, t0, loss = kind(policy, data, run_cfg), 0, 0.0, None
        while done < steps + 10:  # 10 untimed steps: allocation, autotuning, capture
            for loss in stepper.epoch():
                done += 1
                if done == 10:
                    if on_cuda:
                        torch.cuda.synchronize(device)
                    t0 = time.perf_counter()
                if done == steps + 10:
                    break
        final = loss.item()  # waits for the queued steps
        out[f"{name}_steps_per_s"] = steps / (time.perf_counter() - t0)
        out[f"{name}_samples_per_s"] = out[f"{name}_steps_per_s"] * batch_size
        out[f"{name}_final_loss"] = final
    if len(kinds) == 2:
        out["speedup"] = out["CudaGraphTrainStep_steps_per_s"] / out["EagerTrainStep_steps_per_s"]
    return out


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


ZARR_WRITER_PARTS = {"writer_files_s": "files", "writer_sync_s": "sync"}
"""A zarr batch's seconds split (``zarr_store.BATCH_SECONDS``): encoding and writing its demos' files (writer
processes or threads), and the one ``syncfs`` that makes them durable (disk-bound where the files are many); the
rest of ``writer_s`` is the lock, the renames and the commit."""


def _collect_timed(env, agent, episodes: int, path: Path, max_steps: int) -> dict[str, Any]:
    """One ``env.collect`` with physics (``env.step``), agent (``agent.act``) and writer (the background thread's
    ``append_prepared`` calls, split as ``ZARR_WRITER_PARTS`` says for zarr) seconds measured (the rollout's
    ``Timers``); the loop's own time is the rest."""
    physics, acting, writing = _Clock(env.device), _Clock(env.device), _Clock("cpu")
    timers = Timers(step=physics.wrap, act=acting.wrap, write=writing.wrap)
    store_before = dict(zarr_store.BATCH_SECONDS)
    t0 = time.perf_counter()
    ref = env.collect(agent=agent, episodes=episodes, path=path, max_steps=max_steps, progress=False,
                      only_successes=True, max_attempts=2 * episodes, timers=timers)
    wall = time.perf_counter() - t0
    ok = ref.metadata["successes"]
    split = ({name: zarr_store.BATCH_SECONDS[part] - store_before[part] for name, part in ZARR_WRITER_PARTS.items()}
             if path.suffix == ".zarr" else {})
    return {"successful_demos": ok, "attempts": ref.metadata["attempts"], "wall_s": wall,
            "demos_per_s": ok / wall, "demos_per_hour": 3600 * ok / wall,
            "physics_s": physics.seconds, "agent_s": acting.seconds, "writer_s": writing.seconds, **split,
            "loop_s": wall - physics.seconds - acting.seconds, "vector_steps": ref.metadata.get("vector_steps"),
            "writer_batches": ref.metadata.get("writer_batches")}


def bench_collect(task_id: str, *, num_envs: int = 4, episodes: int = 16, device: str | None = None,
                  dataset_path: str | Path = "outputs/bench_collect.zarr", prefill: int = 10_000,
                  max_steps: int = 1000, seed: int = 0, start_gate: Callable[[], None] | None = None) -> dict[str, Any]:
    """Expert collection throughput (successful demos/s and per hour) with its seconds split into physics, agent
    and writer, bytes per stored demo, the first-use (compile) time measured apart, and the same run appending
    to a dataset that already holds ``prefill`` episodes (copies of the first demo, written in batches).
    ``started_at`` / ``ended_at`` (Unix seconds) bound the timed run, for ``bench_collect_on_workers``; one
    ``syncfs`` of the dataset's filesystem (``presync_s``) comes before it, and ``start_gate()``, when given, right
    after the first use (``bench_collect_on_workers`` lines the workers' timed runs up with it)."""
    from .agents import expert_agent  # deferred: the agents import the planner's IK

    path = Path(dataset_path)
    if path.exists():
        raise FileExistsError(f"{path} exists; bench-collect writes a fresh dataset (choose a new --dataset-path)")
    output_path(path)
    t0 = time.perf_counter()
    env = make_env(task_id, num_envs=num_envs, device=device, seed=seed, randomize=True, cameras=False)
    agent = expert_agent(env)
    warm = path.with_name(f"{path.stem}_warmup{path.suffix}")  # first use: kernels, IK solver, writer
    _collect_timed(env, agent, 1, warm, max_steps)  # compiles the step, the IK solves and the writer path
    first_use = time.perf_counter() - t0
    out: dict[str, Any] = {"task": task_id, "device": str(env.device), "num_envs": num_envs, "episodes": episodes,
                           "device_name": torch.cuda.get_device_name(env.device.ordinal) if env.device.is_cuda
                           else "cpu", "first_use_s": first_use, "format": path.suffix,
                           "gpu": os.environ.get("CUDA_VISIBLE_DEVICES")}  # the host's GPU id behind a pinned cuda:0
    if start_gate is not None:
        out["ready_at"] = time.time()
        start_gate()
    t1 = time.perf_counter()
    sync_tree(path.parent)  # earlier writes (a deleted dataset's millions of files) are not charged to this run
    out["presync_s"] = time.perf_counter() - t1
    out["started_at"] = time.time()
    out.update(_collect_timed(env, agent, episodes, path, max_steps))
    out["ended_at"] = time.time()
    size, inodes = _footprint(path)
    out["bytes_per_demo"] = size / max(out["successful_demos"], 1)
    out["inodes_per_demo"] = inodes / max(out["successful_demos"], 1)  # what a zarr dataset spends of an ext4 disk
    out["physics_s_per_step"] = out["physics_s"] / max(out["vector_steps"] or 1, 1)
    out["agent_plus_writer_s_per_step"] = (out["agent_s"] + out["writer_s"]) / max(out["vector_steps"] or 1, 1)
    if prefill > 0:
        demo = read_episode(warm, list_demos(warm)[0])
        full = path.with_name(f"{path.stem}_prefilled{path.suffix}")
        t1 = time.perf_counter()
        with open_writer(full, task_id=task_id, env_args=env_args(env)) as w:
            item = ({k: v for k, v in demo.items() if k != "attrs"}, True, None)
            for start in range(0, prefill, 512):
                w.append_episodes([item] * min(512, prefill - start))
        out["prefill_episodes"], out["prefill_s"] = prefill, time.perf_counter() - t1
        again = _collect_timed(env, agent, episodes, full, max_steps)
        out["prefilled_demos_per_s"] = again["demos_per_s"]
        out["prefilled_writer_s"] = again["writer_s"]
    return out


def bench_collect_on_workers(task_id: str, *, workers: int, num_envs: int = 4, episodes: int = 16,
                             device: str | None = None, dataset_path: str | Path = "outputs/bench_collect.zarr",
                             max_steps: int = 1000, baseline: bool = False) -> dict[str, Any]:
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
        raise ValueError(f"--workers {workers} needs {workers} GPUs, this host shows {len(gpus)}; "
                         f"use --workers {len(gpus)} or a --device to share")
    path = Path(dataset_path)
    shards = [path.with_name(f"{path.stem}_w{i}{path.suffix}") for i in range(workers)]
    alone = [path.with_name(f"{path.stem}_alone{n}{path.suffix}") for n in ("", "2")] if baseline else []
    written = shards + alone
    for p in written + [s.with_name(f"{s.stem}_warmup{s.suffix}") for s in written]:
        if p.exists():
            raise FileExistsError(f"{p} exists; bench-collect writes fresh shards (choose a new --dataset-path)")
    opts = cluster_options(workers, device, gpus=gpus)
    quiet_shutdown()
    run = functools.partial(bench_collect, task_id, num_envs=num_envs, device="cuda" if gpus else device, prefill=0,
                            max_steps=max_steps)
    with opts.get("cluster_class", LocalCluster)(**opts["cluster_kwargs"]) as cluster, Client(cluster) as client:
        client.wait_for_workers(workers)
        # one task per worker, by name (a restarted worker keeps it): two gated runs on one worker would wait forever
        names = sorted((w["name"] for w in client.scheduler_info()["workers"].values()), key=str)

        def alone_run(shard: Path) -> dict[str, Any]:  # worker 0 alone (its GPU, its process), one worker's share
            return client.submit(run, episodes=episodes // workers, dataset_path=str(shard), seed=0, pure=False,
                                 workers=[names[0]], allow_other_workers=False).result()

        lone = [alone_run(alone[0])] if baseline else []
        gate = f"bench-collect-{uuid.uuid4().hex}"
        futures = [client.submit(run, episodes=episodes // workers + (i < episodes % workers), dataset_path=str(shard),
                                 seed=i, start_gate=_StartGate(gate, i), pure=False, workers=[names[i]],
                                 allow_other_workers=False)
                   for i, shard in enumerate(shards)]
        _open_gate(client, gate, futures)
        parts = client.gather(futures)
        lone += [alone_run(alone[1])] if baseline else []
    ok = sum(p["successful_demos"] for p in parts)
    span = max(p["ended_at"] for p in parts) - min(p["started_at"] for p in parts)
    keep = ("device", "device_name", "successful_demos", "wall_s", "demos_per_hour", "first_use_s", "physics_s",
            "agent_s", "loop_s", "writer_s", *ZARR_WRITER_PARTS, "presync_s", "writer_batches", "bytes_per_demo",
            "inodes_per_demo", "gpu", "ready_at", "started_at")
    return {"task": task_id, "workers": workers, "num_envs": num_envs, "episodes": episodes,
            "device_names": [p["device_name"] for p in parts], "format": path.suffix, "successful_demos": ok,
            "wall_s": span, "demos_per_s": ok / span, "demos_per_hour": 3600 * ok / span,
            "first_use_s": max(p["first_use_s"] for p in parts),
            "start_skew_s": max(p["started_at"] for p in parts) - min(p["started_at"] for p in parts),
            "per_worker": [{k: p[k] for k in keep if k in p} | {"dataset_path": str(s)} for p, s in zip(parts, shards)],
            **({} if not lone else {
                "scaling": ok / span / (sum(r["demos_per_s"] for r in lone) / len(lone)),
                "baseline": [{k: r[k] for k in (*keep, "demos_per_s") if k in r} | {"dataset_path": str(a)}
                             for r, a in zip(lone, alone)]})}


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
