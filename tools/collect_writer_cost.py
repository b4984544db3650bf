"""What the collection writer costs, without physics: real demos of a stored dataset (``--source``, e.g. a CPU
``bench-collect`` of PickCube) handed to the background writer the way ``collect`` hands them (``put_many`` of
``--batch`` demos at a time, each written before the next comes, ``EpisodeWriter.prepare`` in the caller's thread),
``--demos`` in all, into a fresh zarr dataset under ``--dir``. Each demo is a distinct copy (its floats scaled by 1 + k
* 1e-7, so that no two compress as one). Prints one JSON line: the writer thread's seconds (``writer_s``, what
``bench-collect`` reports,
split into ``writer_files_s`` / ``writer_sync_s``), the caller's seconds handing the demos over (``feed_s``) and
waiting for the writer at the end (``drain_s``), writer demos/s, CPU milliseconds per demo (this process's threads:
what a busy host pays), bytes and files per demo. ``--profile`` also prints the 25 costliest calls of one batch
written in this thread (cProfile).

    .venv/bin/python tools/collect_writer_cost.py --source src.zarr --dir /tmp/wc [--demos 2048] [--batch 140]
        [--profile] [--loop PYTHON_MS WAIT_MS PER_STEP]

``--loop`` feeds as a collect loop does instead (the writer gathering as ``collect``'s does) and adds the loop's
slowdown: its seconds over steps x (PYTHON_MS + WAIT_MS), the GIL the writer takes from the loop.
"""

from __future__ import annotations

import argparse
import cProfile
import inspect
import json
import pstats
import shutil
import time
from pathlib import Path

import numpy as np

from newton_lab.datasets import list_demos, open_writer, read_dataset_info, read_episodes
from newton_lab.datasets.writers.background_thread import BackgroundWriter
from newton_lab.datasets.zarr import store as zarr_store


def _scaled(tree: dict, k: int) -> dict:
    return {
        key: _scaled(v, k)
        if isinstance(v, dict)
        else (v * np.float32(1 + k * 1e-7)).astype(v.dtype)
        if v.dtype.kind == "f"
        else v.copy()
        for key, v in tree.items()
    }


def _footprint(path: Path) -> tuple[int, int]:
    nodes = list(path.rglob("*"))
    return sum(p.stat().st_size for p in nodes if p.is_file()), len(nodes)


def _cpu_s() -> float:
    """CPU seconds of this process (every thread) so far."""
    return time.process_time()


def _python(n: int) -> None:
    x = 0
    for i in range(n):
        x += i


def _calibrate(ms: float) -> int:
    """Iterations of ``_python`` that take ``ms`` alone (best of 5)."""
    best = min(_timed_python(100_000) for _ in range(5))
    return int(100_000 * ms / 1e3 / best)


def _timed_python(n: int) -> float:
    t0 = time.perf_counter()
    _python(n)
    return time.perf_counter() - t0


def measure(
    source: str, root: Path, demos: int, batch: int, profile: bool, loop: tuple[float, float, int] | None = None
) -> dict:
    stored = list(read_episodes(source, list_demos(source), attrs=True))
    info = read_dataset_info(source)
    task, env_args = info["task_id"], info["env_args"]
    items = []
    for k in range(demos):
        ep = stored[k % len(stored)]
        items.append(
            (
                _scaled({key: v for key, v in ep.items() if key != "attrs"}, k // len(stored)),
                True,
                {"seed": 0, "env_index": k % 4096},
            )
        )
    raw = sum(v.nbytes for v in _leaves(items[0][0]))
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    path = root / "w.zarr"
    writer_s = [0.0]

    def timed(fn):
        def wrapper(*a, **kw):
            t0 = time.perf_counter()
            try:
                return fn(*a, **kw)
            finally:
                writer_s[0] += time.perf_counter() - t0

        return wrapper

    store = open_writer(path, task_id=task, env_args=env_args)
    store.append_episodes(items[:batch])  # first use: writer processes started, caches filled (not counted)
    before = dict(zarr_store.BATCH_SECONDS)
    inner = store.append_prepared
    store.append_prepared = timed(inner)
    gather = (
        {"min_batch": 256, "max_wait_s": 1.0}
        if loop and "min_batch" in inspect.signature(BackgroundWriter).parameters
        else {}
    )  # as collect's writer gathers (where this version has it)
    writer = BackgroundWriter(store, max_queued=max(256, 4096), **gather)
    extra: dict = {}
    cpu0 = _cpu_s()
    t0, feed = time.perf_counter(), 0.0
    if loop:  # simulated steps: Python holding the GIL, a wait releasing it (a GPU sync), the ended demos queued
        python_ms, wait_ms, per_step = loop
        work = _calibrate(python_ms)
        steps = 0
        for a in range(batch, demos, per_step):
            _python(work)
            time.sleep(wait_ms / 1e3)
            t1 = time.perf_counter()
            writer.put_many(items[a : a + per_step])
            feed += time.perf_counter() - t1
            steps += 1
        loop_s = time.perf_counter() - t0
        extra = {
            "steps": steps,
            "loop_s": loop_s,
            "ideal_loop_s": steps * (python_ms + wait_ms) / 1e3,
            "loop_slowdown": loop_s / (steps * (python_ms + wait_ms) / 1e3),
        }
    else:
        for a in range(batch, demos, batch):
            t1 = time.perf_counter()
            writer.put_many(items[a : a + batch])
            feed += time.perf_counter() - t1
            writer.flush()  # one batch of ``batch`` demos at a time, as on a GPU (102-131 batches per 16,384 demos)
    t1 = time.perf_counter()
    writer.close()
    end = time.perf_counter()
    cpu = _cpu_s() - cpu0
    written = demos - batch
    size, files = _footprint(path / "data")
    out = {
        "demos": written,
        "batch": batch,
        "raw_bytes_per_demo": raw,
        "wall_s": end - t0,
        "feed_s": feed,
        "drain_s": end - t1,
        "writer_s": writer_s[0],
        "writer_batches": writer.batches,
        "writer_files_s": zarr_store.BATCH_SECONDS["files"] - before["files"],
        "writer_sync_s": zarr_store.BATCH_SECONDS["sync"] - before["sync"],
        "writer_demos_per_s": written / writer_s[0],
        "cpu_ms_per_demo": 1e3 * cpu / written,
        "bytes_per_demo": size / demos,
        "files_per_demo": files / demos,
        **extra,
    }
    if profile:
        store = open_writer(path, task_id=task, env_args=env_args)
        prepared = [store.prepare(ep, success=ok, attrs=attrs) for ep, ok, attrs in items[:batch]]
        prof = cProfile.Profile()
        prof.runcall(store.append_prepared, prepared)
        print(json.dumps(out))
        pstats.Stats(prof).sort_stats("cumulative").print_stats(25)
    shutil.rmtree(root, ignore_errors=True)
    return out


def _leaves(tree: dict):
    for v in tree.values():
        yield from (_leaves(v) if isinstance(v, dict) else [np.asarray(v)])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--source", required=True)
    p.add_argument("--dir", required=True, type=Path)
    p.add_argument("--demos", type=int, default=2048)
    p.add_argument("--batch", type=int, default=140)
    p.add_argument("--profile", action="store_true")
    p.add_argument(
        "--loop",
        nargs=3,
        type=float,
        metavar=("PYTHON_MS", "WAIT_MS", "PER_STEP"),
        help="feed as a collect loop does: each step PYTHON_MS of Python (holding the GIL), WAIT_MS of "
        "waiting (releasing it, as a GPU sync), then PER_STEP demos queued; prints the loop's slowdown",
    )
    a = p.parse_args()
    loop = None if a.loop is None else (a.loop[0], a.loop[1], int(a.loop[2]))
    print(json.dumps(measure(a.source, a.dir, a.demos, a.batch, a.profile, loop)))


if __name__ == "__main__":
    main()
