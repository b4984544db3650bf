"""Image frames carried as the compressed chunks an HDF5 dataset stores them in (one frame a chunk, deflate), so that
a copy into another HDF5 dataset (the split by phase) writes the same chunk bytes instead of decoding and encoding
every frame again.

Why: splitting PickToShelf's 600 two-camera demos by phase spent its time inflating and deflating frames (90 s on an
H200 host, a fifth of the pipeline's time before training); copying a chunk is a read and a write of ~1 KB.
``h5py``'s ``read_direct_chunk`` / ``write_direct_chunk`` move the bytes; ``__array__`` inflates them (zlib: HDF5's
deflate filter is a zlib stream), so any other reader still gets the frames.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence

import h5py
import numpy as np


class StoredFrames:
    """Frames (T, H, W[, C]) as ``(filter_mask, bytes)`` per frame of a deflate-compressed dataset chunked one frame a
    chunk; ``compression_opts`` is the deflate level the source was written with."""

    def __init__(
        self, shape: Sequence[int], dtype: np.dtype, chunks: Sequence[tuple[int, bytes]], compression_opts: int
    ) -> None:
        self.shape, self.dtype = tuple(shape), np.dtype(dtype)
        self.chunks, self.compression_opts = list(chunks), compression_opts
        if len(self.chunks) != self.shape[0]:
            raise ValueError(f"{len(self.chunks)} chunks for {self.shape[0]} frames")

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    @classmethod
    def read(cls, dset: h5py.Dataset) -> StoredFrames | None:
        """The frames of ``dset`` as stored, or None unless it holds them one a chunk, deflate being its only
        filter."""
        one_frame = dset.ndim >= 3 and dset.shape[0] > 0 and dset.chunks == (1, *dset.shape[1:])
        if not one_frame or dset.compression != "gzip" or dset.shuffle or dset.fletcher32 or dset.scaleoffset:
            return None
        rest = (0,) * (dset.ndim - 1)
        chunks = [dset.id.read_direct_chunk((i, *rest)) for i in range(dset.shape[0])]
        return cls(dset.shape, dset.dtype, chunks, dset.compression_opts)

    def select(self, rows: np.ndarray) -> StoredFrames:
        """The frames at ``rows`` (indices along time)."""
        return StoredFrames(
            (len(rows), *self.shape[1:]), self.dtype, [self.chunks[i] for i in rows], self.compression_opts
        )

    def write(self, group: h5py.Group, key: str) -> None:
        """The dataset ``key`` of ``group`` with these chunks, chunked and filtered as the source was."""
        dset = group.create_dataset(
            key,
            shape=self.shape,
            dtype=self.dtype,
            chunks=(1, *self.shape[1:]),
            compression="gzip",
            compression_opts=self.compression_opts,
        )
        rest = (0,) * (self.ndim - 1)
        for i, (mask, data) in enumerate(self.chunks):
            dset.id.write_direct_chunk((i, *rest), data, mask)

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        """The frames inflated (a chunk whose deflate was skipped, filter mask bit 0, is stored raw)."""
        frames = [zlib.decompress(data) if not mask & 1 else data for mask, data in self.chunks]
        out = np.frombuffer(b"".join(frames), self.dtype).reshape(self.shape)
        return out.astype(dtype) if dtype is not None else out.copy()
