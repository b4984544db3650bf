"""Who writes a zarr batch's files: by default this process, a batch's packs on ``PACK_THREADS`` chunk threads
(``_write_packs``: zstd and the file writes release the GIL; the Python per pack is a few milliseconds) and the demo
groups of a small batch on ``WRITE_THREADS`` threads; with ``NEWTON_LAB_ZARR_WRITE_PROCESSES`` >= 1, a large
batch's demos are encoded and written by that many child processes instead, each fed its share through a pipe.

Why threads by default (``tools/collect_writer_cost.py``, benchmarks history): the processes were there for the
~10 ms of Python per demo group (~80 files); a pack's Python is per array, not per demo, and what is left, zstd and
writing, runs without the GIL. The processes cost a pickled copy of every array through a pipe and back out (the
feed is sequential), and a batch of ~140 demos used only two of them (``zarr_packs.PACK_MIN_PART``).

Hand-written on ``subprocess`` pipes rather than ``multiprocessing``: its spawn and forkserver starts re-import
the user's ``__main__`` (a script without a main guard would start writers recursively), and a fork would copy
a parent that holds CUDA, zarr's event-loop thread and the simulation's threads half-way.

Protocol: the parent pickles a list of jobs (a demo ``(folder, attrs, tree)`` or a ``zarr_packs.PackJob``) to a
child's stdin; the child writes them with ``zarr_packs.write_job`` and answers ``("ok", leftovers)`` (the arrays
that need zarr-python, written by the parent) or ``("error", exception)``. A child whose parent died reads EOF
and exits.
"""

from __future__ import annotations

import functools
import os
import pickle
import subprocess
import threading
from concurrent.futures import ThreadPoolExecutor, wait
from pathlib import Path
from typing import Any

import numpy as np
import zarr

from ._common import child_pipes, fault_injected, start_child
from .zarr_nodes import array_kwargs
from .zarr_packs import PackJob, write_job
from .zarr_session import FaultStore

Job = tuple[Path, dict[str, Any], dict[str, Any]] | PackJob
"""(demo folder in the staging folder, demo attrs, nested tree of arrays), or a pack of demos."""
Leftover = tuple[Path, str, np.ndarray]
"""(demo or pack folder, array path inside it, value): an array ``zarr_nodes`` leaves to zarr-python."""


WRITE_PROCESSES = int(os.environ.get("NEWTON_LAB_ZARR_WRITE_PROCESSES", "0"))
"""Writer processes of a large batch (0, the default: the store writes every batch in this process, on threads)."""
PROCESS_MIN_BATCH = 32
"""Batches of at least this many demos go to the writer processes."""
_shared: WriterProcesses | None = None
_shared_lock = threading.Lock()


def shared() -> WriterProcesses:
    """This process's writer processes (``WRITE_PROCESSES`` of them), made on first use."""
    global _shared
    with _shared_lock:
        if _shared is None or _shared.n != WRITE_PROCESSES:
            _shared = WriterProcesses(WRITE_PROCESSES)
        return _shared


class WriterDied(RuntimeError):
    """A writer process ended without answering (killed, out of memory)."""


def write_jobs(jobs: list[Job]) -> list[Leftover]:
    """Write each job's demo or pack; returns the arrays left to zarr-python."""
    leftovers: list[Leftover] = []
    for job in jobs:
        write_job(job, fallback=lambda node, rel, value: leftovers.append((node, rel, value)))
    return leftovers


class WriterProcesses:
    """``n`` long-lived writer processes, started on first use. One batch at a time (a lock serialises callers)."""

    def __init__(self, n: int) -> None:
        self.n = n
        self._procs: list[subprocess.Popen] = []
        self._lock = threading.Lock()

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self._procs]

    def _start(self) -> None:
        if len(self._procs) == self.n and all(p.poll() is None for p in self._procs):
            return
        self.close()
        self._procs = [start_child(__name__, "serve") for _ in range(self.n)]

    def write(self, jobs: list[Job]) -> list[Leftover]:
        """Write ``jobs`` spread over the processes; returns every process's leftovers. Raises the first error
        once every process answered (nothing is still writing), :class:`WriterDied` if one ended."""
        with self._lock:
            self._start()
            procs = self._procs[:min(self.n, len(jobs))]
            died, answers = False, []
            for i, proc in enumerate(procs):
                try:
                    pickle.dump(jobs[i::len(procs)], proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
                    proc.stdin.flush()
                except (BrokenPipeError, OSError):
                    died = True
                    procs = procs[:i]
                    break
            for proc in procs:
                try:
                    answers.append(pickle.load(proc.stdout))
                except (EOFError, OSError, pickle.UnpicklingError):
                    died = True
            if died:
                self.close()
                raise WriterDied(f"a zarr writer process died while writing a batch of {len(jobs)} demos")
            errors = [value for kind, value in answers if kind == "error"]
            if errors:
                raise errors[0]
            return [item for _, value in answers for item in value]

    def close(self) -> None:
        """Stop the processes (they exit on EOF; a stuck one is killed)."""
        procs, self._procs = self._procs, []
        for proc in procs:
            try:
                proc.stdin.close()
                proc.wait(10)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()


WRITE_THREADS = int(os.environ.get("NEWTON_LAB_ZARR_WRITE_THREADS", "4"))
"""Threads writing a small batch's demos (file creation waits on the filesystem, not on the GIL)."""
PACK_THREADS = int(os.environ.get("NEWTON_LAB_ZARR_PACK_THREADS", str(min(8, os.cpu_count() or 2))))
"""Threads encoding and writing the chunks of a batch's packs in this process (``_write_packs``)."""


class _Submitted(list):
    """The futures of chunk calls handed to ``pool`` as they come (``append``: a call)."""

    def __init__(self, pool: ThreadPoolExecutor) -> None:
        super().__init__()
        self.pool = pool

    def append(self, call) -> None:  # type: ignore[override]
        super().append(self.pool.submit(call))


def _write_packs(path: Path, jobs: list[Job]) -> None:
    """Packs written in this process: their folders, metadata and arrays (concatenated) on this thread, each
    chunk's zstd and file on ``PACK_THREADS`` threads as soon as its array is ready; both release the GIL, so
    nothing is copied to another process (a batch's arrays crossed a pipe twice to reach a writer process)."""
    leftovers: list[Leftover] = []
    with ThreadPoolExecutor(max(1, PACK_THREADS), thread_name_prefix="zarr-pack") as pool:
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


def write_batch(path: Path, jobs: list[Job]) -> None:
    """Write every job of ``jobs`` into the store ``path``: a large batch on the writer processes when there are
    any (``WRITE_PROCESSES``), packs on this process's chunk threads (``_write_packs``), demo groups of a small
    batch (or of any under an injected test fault, which lives in this process) on ``WRITE_THREADS`` threads.
    Returns when every writer stopped; raises the first error."""
    demos = sum(len(job.ids) if isinstance(job, PackJob) else 1 for job in jobs)
    if demos >= PROCESS_MIN_BATCH and WRITE_PROCESSES >= 1 and not fault_injected():
        try:
            leftovers = shared().write(jobs)
        except WriterDied as e:
            raise RuntimeError(f"{e} to {path}; none of the batch was committed") from None
        for node, rel, value in leftovers:
            write_with_zarr(path, node, rel, value)
    elif any(isinstance(job, PackJob) for job in jobs):
        _write_packs(path, jobs)
    elif len(jobs) < 2 or WRITE_THREADS < 2:
        for job in jobs:
            _write_job(path, job)
    else:
        with ThreadPoolExecutor(min(WRITE_THREADS, len(jobs)), thread_name_prefix="zarr-write") as pool:
            futures = [pool.submit(_write_job, path, job) for job in jobs]
            wait(futures)  # nothing may still be writing when the caller removes the staging folder
        for future in futures:
            future.result()


def write_with_zarr(path: Path, demo: Path, rel: str, value: np.ndarray) -> None:
    """One array of a staged demo or pack written by zarr-python (what ``zarr_nodes`` leaves to it)."""
    parent, _, name = rel.rpartition("/")
    node = (demo / parent).relative_to(path).as_posix()
    group = zarr.open_group(store=FaultStore(path), path=node, mode="r+", zarr_format=3)
    group.create_array(name, data=value, **array_kwargs(value))


def serve() -> None:
    """Child side: answer one pickled job list after another until stdin closes. The answers go to the original
    stdout; anything printed goes to stderr."""
    src, dst = child_pipes()
    while True:
        try:
            jobs = pickle.load(src)
        except EOFError:
            return
        try:
            answer: tuple[str, Any] = ("ok", write_jobs(jobs))
        except Exception as e:  # noqa: BLE001 - handed to the parent, which raises it
            answer = ("error", e)
        pickle.dump(answer, dst, protocol=pickle.HIGHEST_PROTOCOL)
        dst.flush()
