"""An array joined along time from pieces that stay where they are: a writer process's image frames, written
straight from the shared ring they came in (``datasets.writers.process``) instead of copied out of it and joined.

Why: two-camera PickToShelf demos are ~17 MB of frames each; copying a burst out of the ring into fresh memory and
joining a batch's bursts again moved every frame twice through first-touched pages (~4 GB/s on one core), and the
collector waited for ring room meanwhile. A chunk of a zarr pack is ~1 MB of rows: :meth:`RowPieces.rows` builds it
from its pieces (a view when one piece holds it) on the thread that encodes it. numpy has no lazy concatenation, so
this small class does it.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from typing import Any

import numpy as np


class RowPieces:
    """Arrays of one dtype and trailing shape, joined along axis 0 without copying (a numpy-like, read-only view:
    ``shape``, ``dtype``, slices along axis 0, ``np.asarray`` joins them)."""

    def __init__(self, pieces: list[np.ndarray]) -> None:
        if not pieces:
            raise ValueError("RowPieces needs at least one piece")
        first = pieces[0]
        for piece in pieces:
            if piece.dtype != first.dtype or piece.shape[1:] != first.shape[1:]:
                raise ValueError(
                    f"RowPieces pieces differ: {piece.dtype} {piece.shape[1:]} against {first.dtype} {first.shape[1:]}"
                )
        self.pieces = list(pieces)
        self._starts = np.concatenate([[0], np.cumsum([len(p) for p in pieces])]).tolist()

    @classmethod
    def join(cls, parts: list[RowPieces]) -> RowPieces:
        """The pieces of ``parts``, one after another."""
        return cls([piece for part in parts for piece in part.pieces])

    @property
    def dtype(self) -> np.dtype:
        return self.pieces[0].dtype

    @property
    def shape(self) -> tuple[int, ...]:
        return (self._starts[-1], *self.pieces[0].shape[1:])

    @property
    def ndim(self) -> int:
        return self.pieces[0].ndim

    @property
    def itemsize(self) -> int:
        return self.dtype.itemsize

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    @property
    def nbytes(self) -> int:
        return self.size * self.itemsize

    def __len__(self) -> int:
        return self._starts[-1]

    def rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start .. stop`` (clipped to the length): a view of one piece when it holds them all, else a copy."""
        start, stop = max(0, min(start, len(self))), max(0, min(stop, len(self)))
        if stop <= start:
            return self.pieces[0][:0]
        first = bisect_right(self._starts, start) - 1
        parts = []
        while start < stop:
            a, b = self._starts[first], self._starts[first + 1]
            parts.append(self.pieces[first][start - a : min(stop, b) - a])
            start, first = min(stop, b), first + 1
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def __getitem__(self, key: Any) -> np.ndarray:
        """A slice along axis 0 (step 1) is :meth:`rows`; anything else indexes the joined array."""
        if isinstance(key, slice) and key.step in (None, 1):
            start, stop, _ = key.indices(len(self))
            return self.rows(start, stop)
        return np.asarray(self)[key]

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        joined = np.concatenate(self.pieces)
        return joined if dtype is None else joined.astype(dtype, copy=False)

    def __repr__(self) -> str:
        return f"RowPieces({len(self.pieces)} pieces, shape={self.shape}, dtype={self.dtype})"
