"""The recording side of ``collect``: the episodes that end in one step are gathered together, checked, and handed as
one batch to a background writer: a thread (``datasets.writers.background_thread``: one device->host copy, the trees
built here) or a process (``datasets.writers.process``: the block copied once into shared memory, packed there)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from ..datasets.writers.background_thread import BackgroundWriter
from ..datasets.writers.columns import DemoBlock
from ..datasets.writers.process import ProcessWriter
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
    """Per step: :meth:`fetch` the rows that ended (one gather, checked finite on the device), :meth:`save` each
    finished record, then :meth:`submit` the step's episodes to the writer as one batch. :meth:`close` waits for the
    writer."""

    def __init__(self, writer: BackgroundWriter | ProcessWriter, recorder, *, seed: int, only_successes: bool) -> None:
        self.writer, self.recorder, self.seed, self.only_successes = writer, recorder, seed, only_successes
        self.blocks = isinstance(writer, ProcessWriter)
        """Episodes go to the writer as column blocks (a writer process), not as trees."""
        self._block = None  # the step's ``FetchedRows``, its row -> index, the demos to write of it
        self._futures: list = []

    def fetch(self, rows: np.ndarray, lengths: np.ndarray) -> None:
        """Gather the episodes of ``rows`` (``lengths`` steps each) in one go and check them finite."""
        self._block = None
        if len(rows):
            got = self.recorder.fetch(rows, lengths)
            self._block = (got, {r: k for k, r in enumerate(got.rows)}, [])

    def save(self, row: int, rec: dict[str, Any]) -> dict[str, Any]:
        """Queue the finished episode of ``row`` (its loop record ``rec``) for writing unless it diverged, holds a
        non-finite value or (``only_successes``) failed; returns the updates to ``rec``."""
        if rec["termination_reason"] == DIVERGED or (self.only_successes and not rec["success"]):
            return {}
        if self._block is None or row not in self._block[1]:  # not fetched with its step's rows: on its own
            self.submit()
            self.fetch(np.array([row]), np.array([rec["length"]]))
        got, index, demos = self._block
        # diverged without tripping the guard: dropped and counted as diverged (images aside: depth holds inf)
        if not got.finite[row]:
            return {"termination_reason": DIVERGED, "success": False, "guard_missed": rec["termination_reason"]}
        attrs = {
            "termination_reason": rec["termination_reason"],
            "env_index": rec["env_index"],
            "episode_length": rec["length"],
            "seed": self.seed,
        }
        demos.append((index[row], rec["length"], bool(rec["success"]), attrs))
        return {}

    def submit(self) -> None:
        """Hand the step's episodes to the writer (blocks while its queue is full): to a writer process as the block
        of the rows to write (one copy into shared memory), to the writer thread as their trees (one host copy)."""
        if self._block is None:
            return
        got, _, demos = self._block
        self._block = None
        if not demos:
            return
        keep = [k for k, _, _, _ in demos]
        if keep != list(range(len(got.rows))):  # only the rows to write leave the device
            idx = torch.as_tensor(keep, device=got.stacked.device)
            got = got._replace(stacked=got.stacked[idx], images={k: v[idx] for k, v in got.images.items()})
            demos = [(i, *rest) for i, (_, *rest) in enumerate(demos)]
        span = max(length for _, length, _, _ in demos)
        stacked, images = got.stacked[:, :span], {k: v[:, :span] for k, v in got.images.items()}
        if self.blocks:
            self._futures += self.writer.put_block(stacked, images, demos)
            return
        block = DemoBlock.from_rows(
            self.recorder.layout, stacked.cpu().numpy(), {k: v.cpu().numpy() for k, v in images.items()}, demos
        )
        self._futures += self.writer.put_many(list(zip(block.trees(), block.successes, block.attrs)))

    def close(self) -> None:
        """Submit what is pending and wait until the writer wrote everything (raises the writer's error, e.g.
        disk full, with its one-line message, unless it was raised already)."""
        try:
            self.submit()
        finally:
            self.writer.close()

    def saved_ids(self) -> list[int]:
        """Demo ids of the episodes written, in the order they finished (after :meth:`close`)."""
        if self.blocks:  # one future per part of a block: its demos' ids
            return [demo_id for f in self._futures for demo_id in f.result()]
        return [f.result() for f in self._futures]
