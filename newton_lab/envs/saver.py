"""The recording side of ``collect``: the episodes that end in one step are copied to the host together
(one device->host copy), checked, and handed as one batch to a background writer (``datasets.background``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..datasets.background import BackgroundWriter
from ..task_api.cfg import DIVERGED


def all_finite(tree: dict[str, Any], skip: Any = ()) -> bool:
    """Every floating-point array of a nested episode dict holds only finite values (arrays named in ``skip``
    aside: depth images hold inf where nothing is hit)."""
    for k, v in tree.items():
        if isinstance(v, dict):
            if not all_finite(v, skip):
                return False
        elif k in skip:
            continue
        elif np.issubdtype(np.asarray(v).dtype, np.floating) and not np.isfinite(v).all():
            return False
    return True


class WrappedWriter:
    """An ``EpisodeWriter`` whose batch writes go through ``wrap(writer.append_prepared)`` (e.g. a timer); every
    other attribute is the writer's own."""

    def __init__(self, writer, wrap) -> None:
        self.writer = writer
        self.append_prepared = wrap(writer.append_prepared)

    def __getattr__(self, name: str):
        return getattr(self.writer, name)


class EpisodeSaver:
    """Per step: :meth:`fetch` the rows that ended (their buffers gathered, the host copy started), :meth:`save` each
    finished record, then :meth:`submit`, which builds the episodes, checks them and hands them to the writer as one
    batch. The loop calls :meth:`submit` after it launched the next step, so that on a GPU this host work runs while
    the GPU simulates. :meth:`close` submits what is pending and waits for the writer."""

    def __init__(self, writer: BackgroundWriter, recorder, *, seed: int, only_successes: bool) -> None:
        self.writer, self.recorder, self.seed, self.only_successes = writer, recorder, seed, only_successes
        self._pending = None  # recorder.PendingEpisodes of the last fetch
        self._records: list[tuple[int, dict[str, Any]]] = []  # (row, loop record) saved since the last submit
        self._futures: list = []

    def fetch(self, rows: np.ndarray, lengths: np.ndarray) -> None:
        """Gather the episodes of ``rows`` (``lengths`` steps each) off the recorder and start their host copy (one
        for all rows); call :meth:`submit` first if a previous fetch is still pending."""
        if self._pending is not None:
            raise RuntimeError("EpisodeSaver.fetch: the previous fetch was not submitted")
        self._pending = self.recorder.start_episodes(rows, lengths) if len(rows) else None

    def save(self, row: int, rec: dict[str, Any]) -> None:
        """Queue the finished episode of ``row`` (its loop record ``rec``) for :meth:`submit`, which writes it unless
        it diverged, holds a non-finite value or (``only_successes``) failed, and updates ``rec`` then."""
        self._records.append((row, rec))

    def submit(self) -> int:
        """Build the saved episodes (waiting for their host copy), check them and hand them to the writer as one batch
        (blocks while its queue is full). Returns how many successful records turned out to hold a non-finite value:
        they are now failures (``termination_reason`` ``diverged``), which the loop's success count must drop."""
        pending, records = self._pending, self._records
        self._pending, self._records = None, []
        fetched = self.recorder.finish_episodes(pending) if pending is not None else ({}, {})
        batch, flipped = [], 0
        for row, rec in records:
            was_success = rec["success"]
            item = self._checked(row, rec, fetched)
            flipped += was_success and not rec["success"]
            if item is not None:
                batch.append(item)
        if batch:
            self._futures += self.writer.put_many(batch)
        return flipped

    def _checked(self, row: int, rec: dict[str, Any], fetched) -> tuple | None:
        """The writer's item for ``row``'s episode, or ``None`` when it is not to be written (``rec`` updated when a
        non-finite value turns it into a diverged failure)."""
        if rec["termination_reason"] == DIVERGED or (self.only_successes and not rec["success"]):
            return None
        trees, finite = fetched
        if row not in trees:  # a bug of the loop: the row's buffers may hold its next episode by now
            raise RuntimeError(f"EpisodeSaver: row {row} was saved but not fetched in the same step")
        episode, ok = trees.pop(row), finite[row]
        episode["dones"][-1:] = int(rec["success"])
        # diverged without tripping the guard: dropped and counted as diverged (images aside: depth holds inf)
        if not ok:
            rec.update(termination_reason=DIVERGED, success=False, guard_missed=rec["termination_reason"])
            return None
        attrs = {"termination_reason": rec["termination_reason"], "env_index": rec["env_index"],
                 "episode_length": rec["length"], "seed": self.seed}
        return episode, rec["success"], attrs

    def close(self) -> None:
        """Submit what is pending and wait until the writer wrote everything (raises the writer's error, e.g.
        disk full, with its one-line message, unless it was raised already)."""
        try:
            self.submit()
        finally:
            self.writer.close()

    def saved_ids(self) -> list[int]:
        """Demo ids of the episodes written, in the order they finished (after :meth:`close`)."""
        return [f.result() for f in self._futures]
