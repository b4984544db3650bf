"""Background episode writer: a thread owns an :class:`~newton_lab.datasets.storage.EpisodeWriter` and writes
everything queued so far as one batch (one write session, one fsync), so the simulation does not wait on disk.

Episodes are checked in the caller's thread (bad input raises there, at once). The queue is bounded
(``max_queued`` episodes, ``max_queued_bytes`` of arrays): ``put`` blocks while it is full (back-pressure).
A write that fails (disk full, I/O error, lock timeout, ...) writes none of its batch, and nothing after it
is written; the error is raised in the caller, with its one-line message, at the next ``put`` /
``put_many`` / ``flush`` / ``close``.

Batching: with ``min_batch`` the thread waits until that many episodes are queued (or the oldest has waited
``max_wait_s``, or a ``put`` is blocked, or ``flush`` / ``close`` asks) before it writes, so that a writer faster than
the simulation still writes few large batches: each batch has a fixed cost (lock, ``syncfs``, commit), and a zarr
batch of ``zarr.packs.PACK_MIN_BATCH`` demos or more is packed into a few files instead of ~80 per demo.

Blocks of demos joined by array (``put_block``, a ``columns.DemoBlock``: a writer process's bursts) queue the same
way, each counting as its demos; the blocks of a batch are joined and written as one (``EpisodeWriter.append_block``,
which checks them there).

Crash window: an episode is durable once its future is done. A process killed at any moment keeps every
episode written before; it loses those queued (at most ``max_queued``, held at most ``max_wait_s`` longer with
``min_batch``) and the one batch being written (all of that batch or none of it lands, see ``storage``).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Iterable, Mapping
from concurrent.futures import Future
from typing import Any

from ..storage import EpisodeItem, EpisodeWriter
from .columns import DemoBlock


def _runs(batch: list[tuple[Any, Future, int]]) -> list[list[tuple[Any, Future, int]]]:
    """``batch`` cut where it turns from trees to blocks or back."""
    runs: list[list[tuple[Any, Future, int]]] = []
    for entry in batch:
        if runs and isinstance(entry[0], DemoBlock) == isinstance(runs[-1][0][0], DemoBlock):
            runs[-1].append(entry)
        else:
            runs.append([entry])
    return runs


class LatchedErrors:
    """The write-error rule both background writers keep (this thread, ``writers.process.ProcessWriter``): the first
    write error is kept (``_error``); every later put, flush or close raises it, except that a close after it was
    raised once does not raise it again. A context manager that closes on exit."""

    _error: BaseException | None = None
    _raised = False

    def _raise(self, always: bool) -> None:
        if self._error is not None and (always or not self._raised):
            self._raised = True
            raise self._error

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self):
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _nbytes(tree: dict[str, Any]) -> int:
    return sum(_nbytes(v) if isinstance(v, dict) else v.nbytes for v in tree.values())


class BackgroundWriter(LatchedErrors):
    """Writes episodes on a thread beside the caller; ``put`` returns a future of the demo id.

    Use as a context manager, or call :meth:`close` (it waits for every queued episode)."""

    def __init__(
        self,
        writer: EpisodeWriter,
        *,
        max_queued: int = 256,
        max_queued_bytes: int = 1 << 30,
        min_batch: int = 1,
        max_wait_s: float = 1.0,
    ) -> None:
        for name, value in (
            ("max_queued", max_queued),
            ("max_queued_bytes", max_queued_bytes),
            ("min_batch", min_batch),
        ):
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not max_wait_s >= 0:
            raise ValueError(f"max_wait_s must be >= 0, got {max_wait_s!r}")
        self.writer, self.max_queued, self.max_queued_bytes = writer, max_queued, max_queued_bytes
        self.min_batch, self.max_wait_s = min(min_batch, max_queued), float(max_wait_s)
        self._since = 0.0  # when the oldest queued episode came
        self._blocked = self._hurry = 0  # puts waiting for room; flush / close calls waiting
        self._bytes = 0  # array bytes queued
        self.batches = 0
        """Batches written (one write session each)."""
        self._cv = threading.Condition()
        self._queue: deque[tuple[Any, Future, int]] = deque()  # (prepared tree or DemoBlock, future, episodes)
        self._episodes = 0  # episodes queued
        self._busy = self._stop = self._closed = False
        self._thread = threading.Thread(target=self._loop, name=f"episode writer {writer.path.name}", daemon=True)
        self._thread.start()

    @property
    def path(self):
        return self.writer.path

    def put(self, episode: Mapping[str, Any], *, success: bool, attrs: Mapping[str, Any] | None = None) -> Future:
        """Queue one episode (see :meth:`put_many`)."""
        return self.put_many([(episode, success, attrs)])[0]

    def put_many(self, episodes: Iterable[EpisodeItem]) -> list[Future]:
        """Queue ``[(episode, success, attrs), ...]``; they are written together unless the queue is behind.
        Blocks while the queue would exceed ``max_queued`` episodes or ``max_queued_bytes`` of arrays (a
        larger group waits for an empty queue).
        Returns one future per episode: its demo id once durable, or the write's error. Do not change the
        arrays after handing them over."""
        if self._closed:
            raise RuntimeError(f"BackgroundWriter for {self.path} is closed")
        items = [(self.writer.prepare(ep, success=ok, attrs=attrs), Future(), 1) for ep, ok, attrs in episodes]
        self._enqueue(items, sum(_nbytes(tree) for (tree, _, _), _, _ in items))
        return [f for _, f, _ in items]

    def put_block(self, block: DemoBlock) -> Future:
        """Queue the demos of a ``columns.DemoBlock`` (they count as ``len(block)`` episodes); they are written with
        the blocks queued beside them as one block (``EpisodeWriter.append_block``). Returns a future of their ids (a
        list) once durable, or of the write's error."""
        if self._closed:
            raise RuntimeError(f"BackgroundWriter for {self.path} is closed")
        item = (block, Future(), len(block))
        self._enqueue([item], block.nbytes)
        return item[1]

    def _enqueue(self, items: list[tuple[Any, Future, int]], size: int) -> None:
        """Add ``(item, future, episodes)`` entries, waiting for room (see :meth:`put_many`)."""
        count = sum(n for _, _, n in items)
        with self._cv:
            self._raise(always=True)

            def room() -> bool:
                return (
                    self._error is not None
                    or not self._queue
                    or not self._thread.is_alive()
                    or (self._episodes + count <= self.max_queued and self._bytes + size <= self.max_queued_bytes)
                )

            if not room():
                self._blocked += 1
                self._cv.notify_all()  # the queue goes now, below min_batch or not: the caller waits for room
                try:
                    self._wait(room)
                finally:
                    self._blocked -= 1
            self._raise(always=True)
            if not self._queue:
                self._since = time.monotonic()
            self._queue.extend(items)
            self._episodes += count
            self._bytes += size
            self._cv.notify_all()

    def flush(self) -> None:
        """Wait until every queued episode is written; raises the write error, if one happened."""
        with self._cv:
            self._hurry += 1
            self._cv.notify_all()
            try:
                self._wait(self._idle)
            finally:
                self._hurry -= 1
            self._raise(always=True)

    def close(self) -> None:
        """Write what is queued, stop the thread and close the writer; raises a write error not raised yet."""
        if self._closed:
            return
        try:
            with self._cv:
                self._hurry += 1
                self._cv.notify_all()
                self._wait(self._idle)
                self._raise(always=False)
        finally:
            with self._cv:
                self._stop = self._closed = True
                self._cv.notify_all()
            self._thread.join()
            self.writer.close()

    def _wait(self, ready) -> None:
        """Wait (holding the lock) until ``ready()``; re-checked twice a second in case the thread died."""
        while not ready():
            self._cv.wait(0.5)

    def _idle(self) -> bool:
        return not (self._queue or self._busy) or not self._thread.is_alive()

    def _due(self) -> bool:
        """The queue is to be written now (under the lock; see the module docstring's Batching)."""
        return bool(self._queue) and (
            self._episodes >= self.min_batch
            or self._blocked > 0
            or self._hurry > 0
            or time.monotonic() - self._since >= self.max_wait_s
        )

    def _loop(self) -> None:
        while True:
            with self._cv:
                while not (self._due() or self._stop):
                    left = self.max_wait_s - (time.monotonic() - self._since) if self._queue else 0.5
                    self._cv.wait(min(0.5, max(left, 0.001)))
                if not self._queue:
                    return
                batch = list(self._queue)
                self._queue.clear()
                self._episodes = self._bytes = 0
                self._busy = True
                self._cv.notify_all()  # room in the queue
            try:
                for run in _runs(batch):  # trees and blocks (not mixed by collect) in write sessions of their own
                    self._write(run)
            finally:
                with self._cv:
                    self._busy = False
                    self._cv.notify_all()

    def _write(self, run: list[tuple[Any, Future, int]]) -> None:
        """One write session of queued trees, or of queued blocks joined into one; each future gets its result."""
        try:
            if self._error is not None:
                raise self._error  # nothing is written after a failed batch
            if isinstance(run[0][0], DemoBlock):
                ids = self.writer.append_block(DemoBlock.join([block for block, _, _ in run]))
                results, at = [], 0
                for _, _, n in run:
                    results.append(ids[at : at + n])
                    at += n
            else:
                results = self.writer.append_prepared([item for item, _, _ in run])
            self.batches += 1
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            for _, f, _ in run:
                f.set_exception(e)
            with self._cv:
                self._error = self._error or e
        else:
            for (_, f, _), result in zip(run, results):
                f.set_result(result)

    def __repr__(self) -> str:
        return f"BackgroundWriter({str(self.path)!r}, max_queued={self.max_queued})"
