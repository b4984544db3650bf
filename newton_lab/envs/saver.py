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
    """Per step: :meth:`fetch` the rows that ended (one copy), :meth:`save` each finished record, then
    :meth:`submit` the step's episodes to the writer as one batch. :meth:`close` waits for the writer."""

    def __init__(self, writer: BackgroundWriter, recorder, *, seed: int, only_successes: bool) -> None:
        self.writer, self.recorder, self.seed, self.only_successes = writer, recorder, seed, only_successes
        self._fetched: dict[int, tuple[dict[str, Any], bool]] = {}  # row -> (episode, every float finite)
        self._batch: list[tuple[dict[str, Any], bool, dict[str, Any]]] = []
        self._futures: list = []

    def fetch(self, rows: np.ndarray, lengths: np.ndarray) -> None:
        """Copy the episodes of ``rows`` (``lengths`` steps each) to the host in one go (and check them finite)."""
        if len(rows):
            trees, finite = self.recorder.episodes(rows, lengths)
            self._fetched = {r: (tree, finite[r]) for r, tree in trees.items()}
        else:
            self._fetched = {}

    def save(self, row: int, rec: dict[str, Any]) -> dict[str, Any]:
        """Queue the finished episode of ``row`` (its loop record ``rec``) for writing unless it diverged, holds a
        non-finite value or (``only_successes``) failed; returns the updates to ``rec``."""
        if rec["termination_reason"] == DIVERGED or (self.only_successes and not rec["success"]):
            return {}
        fetched = self._fetched.pop(row, None)
        if fetched is not None:
            episode, finite = fetched
        else:
            episode = self.recorder.episode(row, rec["length"])
            finite = all_finite(episode, skip=self.recorder.image_terms)
        episode["dones"][-1:] = int(rec["success"])
        # diverged without tripping the guard: dropped and counted as diverged (images aside: depth holds inf)
        if not finite:
            return {"termination_reason": DIVERGED, "success": False, "guard_missed": rec["termination_reason"]}
        attrs = {"termination_reason": rec["termination_reason"], "env_index": rec["env_index"],
                 "episode_length": rec["length"], "seed": self.seed}
        self._batch.append((episode, rec["success"], attrs))
        return {}

    def submit(self) -> None:
        """Hand the step's episodes to the writer (blocks while its queue is full)."""
        self._fetched = {}
        if self._batch:
            batch, self._batch = self._batch, []
            self._futures += self.writer.put_many(batch)

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
