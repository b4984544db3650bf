"""``bench_collect``: expert collection throughput in one process, the first use (compile) measured apart, and the
same run appending to a dataset that already holds many episodes."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from ..datasets import list_demos, open_writer, read_episode
from ..datasets.files.durability import sync_tree
from ..datasets.files.output_paths import output_path
from ..envs import make_env
from ..envs.rollout import env_args
from .timing import collect_timed
from .trace import TRACE_AFTER_STEPS


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
    ``torch.profiler`` trace of ``TRACE_STEPS`` steps of the timed run to this path (``Trace``), after ``trace_after``
    steps; the stage clocks of a traced run read high. ``writer``: ``collect``'s (``"auto"``, ``"thread"``,
    ``"process"``). ``cameras`` (``make_env``'s): the views rendered and recorded every step; their render and the
    frames' copy into the episode buffers are ``record_s`` (the loop's time besides the hand-over and the drain).
    ``task_options``: the task's options (e.g. ``obs_mode``)."""
    from ..agents import expert_agent  # deferred: the agents import the planner's IK

    path = Path(dataset_path)
    if path.exists():
        raise FileExistsError(f"{path} exists; bench-collect writes a fresh dataset (choose a new --dataset-path)")
    output_path(path)
    t0 = time.perf_counter()
    env = make_env(
        task_id, num_envs=num_envs, device=device, seed=seed, randomize=True, cameras=cameras, task_options=task_options
    )
    agent = expert_agent(env)
    _set_replanning(agent, task_id, replan_batch, replan_wait)
    warm = path.with_name(f"{path.stem}_warmup{path.suffix}")  # first use: kernels, IK solver, writer
    collect_timed(env, agent, 1, warm, max_steps, writer=writer)  # compiles the step, the IK solves, the writer path
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
        collect_timed(
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
    out.update(_per_demo_figures(out, env, path))
    if prefill > 0:
        out.update(_prefilled_run(env, agent, warm, path, prefill, episodes, max_steps, writer))
    return out


def _set_replanning(agent, task_id: str, replan_batch: int | None, replan_wait: int | None) -> None:
    """The expert planner's ``replan_batch`` / ``replan_wait`` where given (refused for an expert that does not
    plan)."""
    if (replan_batch, replan_wait) != (None, None) and not hasattr(agent, "replan_batch"):
        raise ValueError(
            f"--replan-batch / --replan-wait: the expert of {task_id} ({type(agent).__name__}) does not plan; drop them"
        )
    if replan_batch is not None:
        agent.replan_batch = replan_batch
    if replan_wait is not None:
        agent.replan_wait = replan_wait


def _per_demo_figures(out: dict[str, Any], env, path: Path) -> dict[str, Any]:
    """Bytes and files per stored demo, the render-and-frames seconds, the cameras, and whether physics bounds the
    run (agent + writer per vector step at most physics per step)."""
    size, inodes = _footprint(path)
    demos, steps = max(out["successful_demos"], 1), max(out["vector_steps"] or 1, 1)
    figures = {
        "bytes_per_demo": size / demos,
        "inodes_per_demo": inodes / demos,  # what a zarr dataset spends of an ext4 disk
        "record_s": max(out["loop_s"] - out["hand_over_s"] - out["drain_s"], 0.0),  # render + frames per step
        "cameras": {
            name: [spec.width, spec.height, list(spec.data)] for name, spec in env.sensors.camera_specs.items()
        },
        "physics_s_per_step": out["physics_s"] / steps,
        "agent_plus_writer_s_per_step": (out["agent_s"] + out["writer_s"]) / steps,
    }
    figures["physics_bound"] = figures["agent_plus_writer_s_per_step"] <= figures["physics_s_per_step"]
    return figures


def _prefilled_run(env, agent, warm: Path, path: Path, prefill: int, episodes: int, max_steps: int, writer: str):
    """The timed collection again, appending to a dataset first filled with ``prefill`` copies of the warm-up demo
    (written in batches of 512): what a large dataset costs the writer."""
    demo = read_episode(warm, list_demos(warm)[0])
    full = path.with_name(f"{path.stem}_prefilled{path.suffix}")
    t1 = time.perf_counter()
    with open_writer(full, task_id=env.task_id, env_args=env_args(env)) as w:
        item = ({k: v for k, v in demo.items() if k != "attrs"}, True, None)
        for start in range(0, prefill, 512):
            w.append_episodes([item] * min(512, prefill - start))
    prefill_s = time.perf_counter() - t1
    again = collect_timed(env, agent, episodes, full, max_steps, writer=writer)
    return {
        "prefill_episodes": prefill,
        "prefill_s": prefill_s,
        "prefilled_demos_per_s": again["demos_per_s"],
        "prefilled_writer_s": again["writer_s"],
    }


def _footprint(path: Path) -> tuple[int, int]:
    """Bytes and inodes (files and folders) of a dataset file or folder."""
    if path.is_file():
        return path.stat().st_size, 1
    nodes = list(path.rglob("*"))
    return sum(p.stat().st_size for p in nodes if p.is_file()), len(nodes) + 1
