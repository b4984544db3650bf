"""How a zarr batch's files are written, all in this process: a batch's packs on ``pack_threads`` chunk threads
(``_write_packs``: zstd and the file writes release the GIL; the Python per pack is a few milliseconds) and the demo
groups of a small batch on ``write_threads`` threads (``ZarrWriteSettings``).

Why threads and no pool of writer processes (``tools/collect_writer_cost.py``, benchmarks history): such a pool
(off by default, now removed) was there for the ~10 ms of Python per demo group (~80 files); a pack's Python is per
array, not per demo, and what is left, zstd and writing, runs without the GIL. The pool cost a pickled copy of every
array through a pipe and back out. The one process ``collect`` keeps is its writer process
(``datasets.writers.process``), which takes the whole write off the simulation's interpreter.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor, wait
from pathlib import Path
from typing import Any

import numpy as np
import zarr

from .nodes import array_kwargs
from .packs import PackJob, write_job
from .session import FaultStore
from .settings import ZarrWriteSettings

Job = tuple[Path, dict[str, Any], dict[str, Any]] | PackJob
"""(demo folder in the staging folder, demo attrs, nested tree of arrays), or a pack of demos."""
Leftover = tuple[Path, str, np.ndarray]
"""(demo or pack folder, array path inside it, value): an array ``zarr.nodes`` leaves to zarr-python."""


class _Submitted(list):
    """The futures of chunk calls handed to ``pool`` as they come (``append``: a call)."""

    def __init__(self, pool: ThreadPoolExecutor) -> None:
        super().__init__()
        self.pool = pool

    def append(self, call) -> None:  # type: ignore[override]
        super().append(self.pool.submit(call))


def _write_packs(path: Path, jobs: list[Job], threads: int) -> None:
    """Packs: their folders, metadata and arrays (concatenated) on this thread, each chunk's zstd and file on
    ``threads`` threads as soon as its array is ready; both release the GIL, so nothing is copied to another
    process."""
    leftovers: list[Leftover] = []
    with ThreadPoolExecutor(max(1, threads), thread_name_prefix="zarr-pack") as pool:
        futures = _Submitted(pool)
        try:
            for job in jobs:
                write_job(job, fallback=lambda node, rel, value: leftovers.append((node, rel, value)), tasks=futures)
        finally:
            wait(futures)  # nothing may still be writing when the caller removes the staging folder
    for future in futures:
        future.result()
    for node, rel, value in leftovers:
        write_with_zarr(path, node, rel, value)


def _write_job(path: Path, job: Job) -> None:
    write_job(job, fallback=functools.partial(write_with_zarr, path))


def write_batch(path: Path, jobs: list[Job], settings: ZarrWriteSettings) -> None:
    """Write every job of ``jobs`` into the store ``path``: packs on ``settings.pack_threads`` chunk threads
    (``_write_packs``), the demo groups of a small batch on ``settings.write_threads`` threads. Returns when every
    writer stopped; raises the first error."""
    if any(isinstance(job, PackJob) for job in jobs):
        _write_packs(path, jobs, settings.pack_threads)
    elif len(jobs) < 2 or settings.write_threads < 2:
        for job in jobs:
            _write_job(path, job)
    else:
        with ThreadPoolExecutor(min(settings.write_threads, len(jobs)), thread_name_prefix="zarr-write") as pool:
            futures = [pool.submit(_write_job, path, job) for job in jobs]
            wait(futures)  # nothing may still be writing when the caller removes the staging folder
        for future in futures:
            future.result()


def write_with_zarr(path: Path, demo: Path, rel: str, value: np.ndarray) -> None:
    """One array of a staged demo or pack written by zarr-python (what ``zarr.nodes`` leaves to it)."""
    parent, _, name = rel.rpartition("/")
    node = (demo / parent).relative_to(path).as_posix()
    group = zarr.open_group(store=FaultStore(path), path=node, mode="r+", zarr_format=3)
    group.create_array(name, data=value, **array_kwargs(value))
