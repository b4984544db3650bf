"""The writer process of ``datasets.writer_process`` (``python -m newton_lab.datasets.writer_serve FD``, FD the shared
ring's descriptor): it copies each burst of ended episodes out of the ring as a ``columns.DemoBlock`` (one gather per
array), answers ``free`` at once, and a thread writes the queued blocks as batches: ``min_batch`` demos or more, or
whatever is queued once the oldest has waited ``max_wait_s`` (``datasets.background``'s batching, counted in demos),
each one ``EpisodeWriter.append_block``: a zarr batch is packed straight from the joined arrays.

Replies on stdout, pickled: ``("free", burst)``, ``("written", burst, ids, seconds, batches)``, ``("error", burst,
exception)``. After a failed batch nothing more is written: every later burst gets the same error. The process ends
at ``close`` or at the end of its stdin (the collector is gone), after writing what it holds.
"""

from __future__ import annotations

import cProfile
import mmap
import os
import pickle
import sys
import threading
import time
from collections import deque
from typing import Any

import numpy as np

from . import zarr_store
from .columns import DemoBlock
from .storage import EpisodeWriter

PROFILE_ENV = "NEWTON_LAB_WRITER_PROFILE"
"""Set to a path: the writer process profiles its batch writes (cProfile) and saves the stats there when it ends."""


class _Batcher:
    """A thread writing the queued blocks in batches (see the module docstring); ``put`` blocks while more than
    ``max_queued`` demos or ``max_queued_bytes`` are queued."""

    def __init__(self, store: EpisodeWriter, reply, *, max_queued: int, max_queued_bytes: int, min_batch: int,
                 max_wait_s: float) -> None:
        self.store, self.reply = store, reply
        self.max_queued, self.max_queued_bytes, self.min_batch, self.max_wait_s = (max_queued, max_queued_bytes,
                                                                                   min_batch, max_wait_s)
        self.seconds, self.batches = 0.0, 0
        self._queue: deque[tuple[int, DemoBlock, float]] = deque()
        self._demos = self._bytes = 0
        self._closing = False
        self._error: BaseException | None = None
        self._cv = threading.Condition()
        path = os.environ.get(PROFILE_ENV)
        self._profile = (cProfile.Profile(), path) if path else None
        self._thread = threading.Thread(target=self._loop, name="batch writer", daemon=True)
        self._thread.start()

    def put(self, burst: int, block: DemoBlock) -> None:
        size = block.frames.nbytes + sum(img.nbytes for img in block.images.values())
        with self._cv:
            while (self._queue and self._error is None and (self._demos + len(block) > self.max_queued
                                                             or self._bytes + size > self.max_queued_bytes)):
                self._cv.wait(0.5)
            self._queue.append((burst, block, time.monotonic()))
            self._demos += len(block)
            self._bytes += size
            self._cv.notify_all()

    def close(self) -> None:
        with self._cv:
            self._closing = True
            self._cv.notify_all()
        self._thread.join()
        if self._profile is not None:
            self._profile[0].dump_stats(self._profile[1])

    def _due(self) -> bool:
        return bool(self._queue) and (self._closing or self._demos >= self.min_batch
                                      or time.monotonic() - self._queue[0][2] >= self.max_wait_s)

    def _loop(self) -> None:
        while True:
            with self._cv:
                while not self._due() and not (self._closing and not self._queue):
                    left = self.max_wait_s - (time.monotonic() - self._queue[0][2]) if self._queue else 0.5
                    self._cv.wait(min(0.5, max(left, 0.001)))
                if not self._queue:
                    return
                batch = list(self._queue)
                self._queue.clear()
                self._demos = self._bytes = 0
                self._cv.notify_all()
            if self._error is None:
                self._write(batch)
            else:  # nothing is written after a failed batch
                for burst, _, _ in batch:
                    self.reply(("error", burst, self._error))

    def _write(self, batch: list[tuple[int, DemoBlock, float]]) -> None:
        t0 = time.perf_counter()
        if self._profile is not None:
            self._profile[0].enable()
        try:
            ids = self.store.append_block(DemoBlock.join([block for _, block, _ in batch]))
        except BaseException as e:  # noqa: BLE001 - handed to the collector
            self._error = _portable(e)
            for burst, _, _ in batch:
                self.reply(("error", burst, self._error))
            return
        finally:
            if self._profile is not None:
                self._profile[0].disable()
            self.seconds += time.perf_counter() - t0
        self.batches += 1
        seconds = {"write": self.seconds, **zarr_store.BATCH_SECONDS}
        at = 0
        for burst, block, _ in batch:
            self.reply(("written", burst, ids[at:at + len(block)], seconds, self.batches))
            at += len(block)


def serve(fd: int, inbox, outbox) -> None:
    """Open the dataset, then turn each burst into a block and queue it; reply as ``ProcessWriter`` expects."""
    lock = threading.Lock()

    def reply(message: tuple) -> None:
        with lock:
            pickle.dump(message, outbox, protocol=pickle.HIGHEST_PROTOCOL)
            outbox.flush()

    _, path, task_id, fsync, ring_bytes, layout, settings = pickle.load(inbox)
    buf = mmap.mmap(fd, ring_bytes)
    batcher = _Batcher(EpisodeWriter.open(path, task_id=task_id, env_args={}, fsync=fsync), reply, **settings)
    try:
        while True:
            try:
                message = pickle.load(inbox)
            except EOFError:
                break
            if message[0] == "close":
                break
            _, burst, specs, demos = message
            try:
                arrays: dict[str, Any] = {
                    name: np.frombuffer(buf, dtype=dtype, count=int(np.prod(shape)), offset=at).reshape(shape)
                    for name, at, shape, dtype in specs}
                block = DemoBlock.from_rows(layout, arrays.pop(""), arrays, demos)  # copies out of the ring
                del arrays
            except Exception as e:  # noqa: BLE001 - handed to the collector
                reply(("free", burst))
                reply(("error", burst, _portable(e)))
                continue
            reply(("free", burst))
            batcher.put(burst, block)
    finally:
        batcher.close()


def _portable(error: BaseException) -> BaseException:
    """``error`` if it survives pickling, else a RuntimeError with its message."""
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:  # noqa: BLE001 - any pickling failure
        return RuntimeError(f"{type(error).__name__}: {error}")


def main() -> None:
    """Entry: the ring's descriptor in ``sys.argv[1]``; messages on stdin, replies on the original stdout."""
    inbox, outbox = sys.stdin.buffer, os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # the pipe carries replies only: anything printed, by Python or a library, goes to stderr
    sys.stdout = sys.stderr
    serve(int(sys.argv[1]), inbox, outbox)


if __name__ == "__main__":
    main()
