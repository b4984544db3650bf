"""Background episode writer: a thread owns an :class:`~newton_lab.datasets.storage.EpisodeWriter` and writes
everything queued so far as one batch (one write session, one fsync), so the simulation does not wait on disk.

Episodes are checked in the caller's thread (bad input raises there, at once). The queue is bounded
(``max_queued`` episodes, ``max_queued_bytes`` of arrays): ``put`` blocks while it is full (back-pressure).
A write that fails (disk full, I/O error, lock timeout, ...) writes none of its batch, and nothing after it
is written; the error is raised in the caller, with its one-line message, at the next ``put`` /
``put_many`` / ``flush`` / ``close``.

Crash window: an episode is durable once its future is done. A process killed at any moment keeps every
episode written before; it loses those queued (at most ``max_queued``) and the one batch being written
(all of that batch or none of it lands, see ``storage``).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Iterable, Mapping
from concurrent.futures import Future
from typing import Any

from .storage import EpisodeItem, EpisodeWriter


def _nbytes(tree: dict[str, Any]) -> int:
    return sum(_nbytes(v) if isinstance(v, dict) else v.nbytes for v in tree.values())


class BackgroundWriter:
    """Writes episodes on a thread beside the caller; ``put`` returns a future of the demo id.

    Use as a context manager, or call :meth:`close` (it waits for every queued episode)."""

    def __init__(self, writer: EpisodeWriter, *, max_queued: int = 256, max_queued_bytes: int = 1 << 30) -> None:
        for name, value in (("max_queued", max_queued), ("max_queued_bytes", max_queued_bytes)):
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        self.writer, self.max_queued, self.max_queued_bytes = writer, max_queued, max_queued_bytes
        self._bytes = 0  # array bytes queued
        self.batches = 0
        """Batches written (one write session each)."""
        self._cv = threading.Condition()
        self._queue: deque[tuple[tuple[dict, dict, int], Future]] = deque()
        self._busy = self._stop = self._closed = self._raised = False
        self._error: BaseException | None = None
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
        items = [(self.writer.prepare(ep, success=ok, attrs=attrs), Future()) for ep, ok, attrs in episodes]
        size = sum(_nbytes(tree) for (tree, _, _), _ in items)
        with self._cv:
            self._raise(always=True)
            self._wait(lambda: self._error is not None or not self._queue or not self._thread.is_alive()
                       or (len(self._queue) + len(items) <= self.max_queued
                           and self._bytes + size <= self.max_queued_bytes))
            self._raise(always=True)
            self._queue.extend(items)
            self._bytes += size
            self._cv.notify_all()
        return [f for _, f in items]

    def flush(self) -> None:
        """Wait until every queued episode is written; raises the write error, if one happened."""
        with self._cv:
            self._wait(self._idle)
            self._raise(always=True)

    def close(self) -> None:
        """Write what is queued, stop the thread and close the writer; raises a write error not raised yet."""
        if self._closed:
            return
        try:
            with self._cv:
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

    def _raise(self, always: bool) -> None:
        if self._error is not None and (always or not self._raised):
            self._raised = True
            raise self._error

    def _loop(self) -> None:
        while True:
            with self._cv:
                self._wait(lambda: self._queue or self._stop)
                if not self._queue:
                    return
                batch = list(self._queue)
                self._queue.clear()
                self._bytes = 0
                self._busy = True
                self._cv.notify_all()  # room in the queue
            try:
                if self._error is not None:
                    raise self._error  # nothing is written after a failed batch
                ids = self.writer.append_prepared([item for item, _ in batch])
                self.batches += 1
            except BaseException as e:  # noqa: BLE001 - handed to the caller
                for _, f in batch:
                    f.set_exception(e)
                with self._cv:
                    self._error = self._error or e
            else:
                for (_, f), demo_id in zip(batch, ids):
                    f.set_result(demo_id)
            finally:
                with self._cv:
                    self._busy = False
                    self._cv.notify_all()

    def __enter__(self) -> BackgroundWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"BackgroundWriter({str(self.path)!r}, max_queued={self.max_queued})"
