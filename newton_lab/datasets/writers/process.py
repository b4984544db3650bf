"""A writer process for ``collect``: ended episodes cross to it as whole column blocks in shared memory, and it writes
them beside the simulation (``datasets.writers.process_main``: joined by array, batched, a zarr batch packed straight
from the columns).

Why a process: with thousands of rows the episodes end in bursts (the rows start together), and in one interpreter
the per-demo Python of a burst (splitting the copy by array, each demo's tree, the writer's checks, the pack's
encoding) waits for the same lock as the simulation loop; bench-collect on a GPU spent more of each step on that
than on physics. Here the collecting process copies a burst once, from the device straight into a shared ring
(``os.memfd_create``: anonymous, freed when both processes let go of it, nothing left in ``/dev/shm`` after a
kill), and sends one small message; the writer process does the rest on its own interpreter, writing image frames
straight from the ring (``datasets.writers.process_main``); a burst's room comes back once it is written. Pipes
carry pickled messages: the standard library's ``multiprocessing`` would start the child by re-importing the
caller's main module (the whole simulator) and refuses to start one from a Dask worker (a daemonic process).

Crash window: as ``datasets.writers.background_thread`` (an episode is durable once its future is done). If the
collecting process is killed, the writer process reads the end of its pipe, writes what it has already received and
exits.
"""

from __future__ import annotations

import ctypes
import math
import mmap
import os
import pickle
import threading
import time
from collections import deque
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import numpy as np
import torch

from ..zarr.settings import ZarrWriteSettings
from .background_thread import LatchedErrors
from .child_process import start_child
from .columns import ColumnLayout

RING_BYTES = 4 << 30
"""Bytes of the shared ring (virtual: pages are backed only once a burst is copied into them, so a collection backs
at most what its bursts pass through). Image frames are written from the ring, half of which holds the write queue:
4 GiB queues ~120 two-camera PickToShelf demos, enough for a zarr pack (``ZarrWriteSettings.pack_min_batch``)."""
_ALIGN = 64


def available() -> bool:
    """This platform can run the writer process (Linux: ``os.memfd_create``)."""
    return hasattr(os, "memfd_create")


class _Ring:
    """First-in first-out allocation of byte ranges in a buffer (the writer frees the bursts in the order they came)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._taken: deque[tuple[int, int]] = deque()  # (start, end) in order

    def take(self, nbytes: int) -> int | None:
        """Start of ``nbytes`` free bytes, or None while the ring is too full."""
        nbytes = -(-nbytes // _ALIGN) * _ALIGN
        if not self._taken:
            start = 0 if nbytes <= self.size else None
        elif self._taken[-1][0] >= self._taken[0][0]:  # in order: room after the newest and before the oldest
            head, tail = self._taken[-1][1], self._taken[0][0]
            start = head if head + nbytes <= self.size else (0 if nbytes <= tail else None)
        else:  # wrapped: the room lies between the newest and the oldest
            head, tail = self._taken[-1][1], self._taken[0][0]
            start = head if head + nbytes <= tail else None
        if start is not None:
            self._taken.append((start, start + nbytes))
        return start

    def give_back(self) -> None:
        """Free the oldest range."""
        self._taken.popleft()

    def held(self) -> int:
        """Ranges taken and not given back."""
        return len(self._taken)


class ProcessWriter(LatchedErrors):
    """The collecting side: :meth:`put_block` copies a burst into the ring and queues it; futures give each demo's id
    once durable (or the write's error). :meth:`close` waits for every queued episode and stops the process."""

    def __init__(
        self,
        path: str | Path,
        *,
        task_id: str,
        layout: ColumnLayout,
        fsync: bool = True,
        max_queued: int = 256,
        max_queued_bytes: int | None = None,
        min_batch: int = 1,
        max_wait_s: float = 1.0,
        ring_bytes: int = RING_BYTES,
        zarr_settings: ZarrWriteSettings | None = None,
        profile_to: str | Path | None = None,
    ) -> None:
        """``max_queued_bytes``: the process's write queue, at most (and by default) half the ring;
        ``zarr_settings``: how the process writes zarr batches (default ``DEFAULT_ZARR_SETTINGS``);
        ``profile_to``: a path where the process saves a cProfile of its batch writes when it ends."""
        self.path, self.layout = Path(path), layout
        self.seconds = {"write": 0.0, "files": 0.0, "sync": 0.0}
        """The writer process's batch writes so far [s]: in all, and for zarr encoding + writing files and syncing."""
        self.batches = 0
        self.hand_over = {"ring_wait": 0.0, "copy": 0.0}
        """The collecting side's own seconds so far in :meth:`put_block`: waiting for room in the ring (the writer
        process has not written earlier bursts yet), and copying bursts into it (from the device: the transfer)."""
        self._fd = os.memfd_create("newton_lab_collect", os.MFD_CLOEXEC)
        os.ftruncate(self._fd, ring_bytes)
        self._buf = mmap.mmap(self._fd, ring_bytes)
        self._ring = _Ring(ring_bytes)
        self._pinned = None  # the ring page-locked for CUDA: at the first burst from a GPU (``_pin``)
        self._cv = threading.Condition()
        self._pending: dict[int, Future] = {}  # burst -> its ids
        self._next = 0
        self._closed = False
        self._proc = start_child(
            "newton_lab.datasets.writers.process_main", "main", str(self._fd), pass_fds=(self._fd,)
        )
        os.set_inheritable(self._fd, False)
        self._send(
            (
                "open",
                str(self.path),
                task_id,
                fsync,
                ring_bytes,
                layout,
                {
                    "max_queued": max_queued,
                    "max_queued_bytes": ring_bytes // 2 if max_queued_bytes is None else max_queued_bytes,
                    "min_batch": min_batch,
                    "max_wait_s": max_wait_s,
                },
                zarr_settings,
                None if profile_to is None else str(profile_to),
            )
        )
        self._reader = threading.Thread(target=self._read, name=f"writer process {self.path.name}", daemon=True)
        self._reader.start()

    def put_block(
        self, stacked, images: dict[str, Any], demos: list[tuple[int, int, bool, dict[str, Any]]]
    ) -> list[Future]:
        """Queue the episodes of a block: ``stacked`` (rows, steps, ``layout.width``) float32 (a torch tensor on any
        device, or numpy), ``images`` term -> (rows, steps, ...) of the same rows, and per demo ``(row in the block,
        length, success, attrs)``. Blocks while the ring has no room. A block larger than a quarter of the ring (many
        long episodes with images) goes in parts of whole rows. Returns one future per part: the ids of its demos (a
        list, once all of them are durable) or the write's error."""
        row_bytes = sum(math.prod(a.shape[1:]) * _itemsize(a) for a in (stacked, *images.values()))
        per_part = max(1, self._ring.size // 4 // max(row_bytes, 1))
        futures = []
        for first in range(0, len(demos), per_part):
            part = demos[first : first + per_part]
            rows = [row for row, _, _, _ in part]
            if len(part) == len(demos):
                futures.append(self._put_part(stacked, images, part))
            else:  # each part's rows, renumbered from 0
                futures.append(
                    self._put_part(
                        stacked[rows],
                        {k: v[rows] for k, v in images.items()},
                        [(k, *rest) for k, (_, *rest) in enumerate(part)],
                    )
                )
        return futures

    def _put_part(self, stacked, images: dict[str, Any], demos: list) -> Future:
        arrays = [("", stacked)] + list(images.items())
        sizes = [-(-math.prod(a.shape) * _itemsize(a) // _ALIGN) * _ALIGN for _, a in arrays]
        waited = time.perf_counter()
        with self._cv:
            self._raise(always=True)
            start = self._ring.take(sum(sizes))
            while start is None:
                if not self._ring.held():
                    raise MemoryError(
                        f"an episode of {sum(sizes) / 2**20:.0f} MiB does not fit the writer's "
                        f"{self._ring.size / 2**20:.0f} MiB ring; record shorter episodes or smaller "
                        f"frames, or pass writer='thread'"
                    )
                self._cv.wait(0.5)
                self._raise(always=True)
                if self._proc.poll() is not None:
                    raise RuntimeError(f"the writer process of {self.path} exited (code {self._proc.returncode})")
                start = self._ring.take(sum(sizes))
            burst, self._next = self._next, self._next + 1
            future = self._pending[burst] = Future()
        copied = time.perf_counter()
        if self._pinned is None and any(isinstance(a, torch.Tensor) and a.is_cuda for _, a in arrays):
            self._pinned = _pin(self._buf, self._ring.size)
        specs, at = [], start
        for (name, arr), n in zip(arrays, sizes):
            _copy_into(self._buf, at, arr)
            specs.append((name, at, tuple(arr.shape), _dtype(arr)))
            at += n
        self.hand_over["ring_wait"] += copied - waited
        self.hand_over["copy"] += time.perf_counter() - copied
        self._send(("burst", burst, specs, demos))  # a failure raises at the next put, flush or close
        return future

    def flush(self) -> None:
        """Wait until every queued episode is written; raises the write error, if one happened."""
        with self._cv:
            while self._pending and self._error is None and self._proc.poll() is None:
                self._cv.wait(0.5)
            self._raise(always=True)

    def close(self) -> None:
        """Write what is queued, stop the process; raises a write error not raised yet."""
        if self._closed:
            return
        self._closed = True
        self._send(("close",))
        try:
            self._proc.stdin.close()
        except OSError:
            pass  # the process is gone already: its exit code tells
        self._proc.wait()
        self._reader.join()
        self._pinned = _unpin(self._pinned)
        self._buf.close()
        os.close(self._fd)
        with self._cv:
            if self._pending and self._error is None:
                self._error = RuntimeError(
                    f"the writer process of {self.path} exited (code {self._proc.returncode}) "
                    f"before writing {len(self._pending)} bursts of episodes"
                )
                for future in self._pending.values():
                    future.set_exception(self._error)
            self._raise(always=False)

    def _send(self, message: tuple) -> None:
        """Send one message; a process that is gone becomes the writer's error (raised by the callers)."""
        try:
            pickle.dump(message, self._proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError, ValueError) as e:  # ValueError: the pipe is closed
            with self._cv:
                self._error = self._error or RuntimeError(f"the writer process of {self.path} is gone ({e})")

    def _read(self) -> None:
        """The process's replies: ``free`` (a burst left the ring), ``written`` (its demo ids), ``error``."""
        while True:
            try:
                message = pickle.load(self._proc.stdout)
            except (EOFError, OSError, pickle.UnpicklingError):
                with self._cv:
                    self._cv.notify_all()
                return
            kind, burst = message[0], message[1]
            with self._cv:
                if kind == "free":
                    self._ring.give_back()
                elif kind == "written":
                    ids, seconds, batches = message[2:]
                    self.seconds.update(seconds)
                    self.batches = batches
                    self._pending.pop(burst).set_result(ids)
                elif kind == "error":
                    self._error = self._error or message[2]
                    if burst in self._pending:
                        self._pending.pop(burst).set_exception(message[2])
                self._cv.notify_all()


def _pin(buf: mmap.mmap, nbytes: int):
    """Page-lock the ring for CUDA (``cudaHostRegister``), so that bursts copied off the device land in it at the
    bus's speed instead of through the driver's pageable staging (bench-collect, one H200, two-camera PickToShelf:
    ~7 GB/s pageable). Returns what ``_unpin`` needs, or ``False`` when the driver refuses (the copies stay correct,
    only slower; not tried again)."""
    view = ctypes.c_char.from_buffer(buf)  # an export of the mapping: released by _unpin before the mapping closes
    address = ctypes.addressof(view)
    if int(torch.cuda.cudart().cudaHostRegister(address, nbytes, 0)) != 0:
        return False
    return view, address


def _unpin(pinned) -> None:
    """Undo ``_pin``; returns ``None`` (the writer's new ``_pinned``)."""
    if pinned:
        torch.cuda.cudart().cudaHostUnregister(pinned[1])
    return None  # dropping the pair releases the export of the mapping


def _itemsize(arr) -> int:
    return arr.element_size() if hasattr(arr, "element_size") else arr.itemsize


def _dtype(arr) -> str:
    """numpy dtype string of a numpy array or torch tensor."""
    return str(arr.dtype).removeprefix("torch.") if hasattr(arr, "element_size") else arr.dtype.str


def _copy_into(buf: mmap.mmap, at: int, arr) -> None:
    """Copy ``arr`` (numpy, or a torch tensor on any device: one device->host copy) into ``buf`` at byte ``at``."""
    if isinstance(arr, torch.Tensor):
        dest = torch.frombuffer(buf, dtype=arr.dtype, count=arr.numel(), offset=at).view(arr.shape)
        dest.copy_(arr)
    else:
        np.frombuffer(buf, dtype=arr.dtype, count=arr.size, offset=at).reshape(arr.shape)[...] = arr
