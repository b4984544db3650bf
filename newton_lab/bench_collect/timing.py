"""One timed ``env.collect``: the device's seconds in the env step, the host's in the agent, the writer, the hand-over
and the final drain (``collect_timed``), with the clocks that measure them."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import warp as wp

from ..datasets.zarr import store as zarr_store
from ..envs.rollout import Timers
from .trace import TRACE_AFTER_STEPS, Trace


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


ZARR_WRITER_PARTS = {"writer_files_s": "files", "writer_sync_s": "sync"}
"""A zarr batch's seconds split (``zarr.store.BATCH_SECONDS``): encoding and writing its demos' files (writer
processes or threads), and the one ``syncfs`` that makes them durable (disk-bound where the files are many); the
rest of ``writer_s`` is the lock, the renames and the commit."""


def collect_timed(
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
    (``loop_s``), of which ``hand_over_s`` passes ended episodes to the writer (gather, checks, the copy off the device,
    queueing; with a writer process also split into ``hand_over_ring_wait_s``, waiting for room in its ring, and
    ``hand_over_copy_s``, copying bursts into it; the process's own ``writer_copy_out_s``, copying their low-dim arrays
    out (the frames are written from the ring), and ``writer_queue_wait_s``, blocked on its full write queue, say why
    the ring has no room) and ``drain_s`` waits for the writer after the last step. ``physics_share`` (physics over
    wall) near 1 means the device's step bounds the loop; the rest of the wall is the host's own work."""
    physics, acting, writing = _DeviceClock(env.device), _Clock(env.device), _Clock("cpu")
    handing, draining = _Clock("cpu"), _Clock("cpu")
    clocks = {"physics": physics, "agent": acting, "writer": writing, "hand-over": handing, "drain": draining}
    tracer = Trace(trace, env.device, trace_after) if trace is not None else None

    timers = _timers(clocks, tracer)
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
        **{f"writer_{k}_s": spent[k] for k in ("copy_out", "queue_wait") if spent and k in spent},
        **{f"hand_over_{k}_s": v for k, v in (ref.metadata.get("hand_over_seconds") or {}).items()},
        "drain_s": draining.seconds,
        "vector_steps": ref.metadata.get("vector_steps"),
        "writer_batches": ref.metadata.get("writer_batches"),
    }


def _timers(clocks: dict, tracer: Trace | None) -> Timers:
    """The rollout's ``Timers`` from the stage clocks, each stage also a labelled range of the trace when one runs
    (and every env step moving the trace's window on)."""

    def timer(name: str):
        if tracer is None:
            return clocks[name].wrap
        if name == "physics":  # each env step also moves the trace's window on
            return lambda fn: tracer.stepping(tracer.wrap(name, clocks[name].wrap(fn)))
        return lambda fn: tracer.wrap(name, clocks[name].wrap(fn))

    return Timers(
        step=timer("physics"),
        act=timer("agent"),
        write=timer("writer"),
        hand_over=timer("hand-over"),
        drain=timer("drain"),
    )
