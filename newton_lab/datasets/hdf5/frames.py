"""Image frames carried as the compressed chunks an HDF5 dataset stores them in (one frame a chunk, deflate), so that
a copy into another HDF5 dataset (the split by phase) writes the same chunk bytes instead of decoding and encoding
every frame again.

Why: splitting PickToShelf's 600 two-camera demos by phase spent its time inflating and deflating frames (90 s on an
H200 host, a fifth of the pipeline's time before training); copying a chunk is a read and a write of ~1 KB.
``h5py``'s ``read_direct_chunk`` / ``write_direct_chunk`` move the bytes; ``__array__`` inflates them (zlib: HDF5's
deflate filter is a zlib stream), so any other reader still gets the frames.

New frames are deflated here too (``deflate``), on threads, before the writer opens the file: HDF5 runs its deflate
filter in the writing thread, one chunk after another, and collecting with two cameras was bound by it (about 150
MB/s of frames on one core at level 4). zlib releases the GIL, so the chunks deflate on every core, and they are the
bytes HDF5's own filter writes (``compress2``, the same zlib stream).
"""

from __future__ import annotations

import functools
import os
import zlib
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

FRAME_DEFLATE_LEVEL = 3
"""zlib level of new frames. Measured on PickToShelf's 96x72 frames (one core): level 3 deflates 240 MB/s of head
and 530 MB/s of wrist frames, level 4 125 and 167 MB/s (4 and up switch to zlib's slower matcher); the files are
about the same size (head 15.0 vs 15.9 : 1, wrist 56.8 vs 53.4 : 1)."""
_FRAMES_PER_TASK = 32  # frames one thread deflates per task: few enough tasks that Python's overhead stays small


@functools.cache
def _pool(pid: int) -> ThreadPoolExecutor:
    """The deflate threads of process ``pid`` (a forked writer process makes its own): one per core, at most 8."""
    return ThreadPoolExecutor(min(8, os.cpu_count() or 1), thread_name_prefix="deflate")


def _deflate_block(frames: np.ndarray, level: int) -> list[tuple[int, bytes]]:
    """(filter mask, bytes) per frame; a frame that deflate would not shrink is kept raw with filter bit 0 set, as
    HDF5 does with its optional deflate filter."""
    out = []
    for frame in frames:
        raw = frame.tobytes()
        packed = zlib.compress(raw, level)
        out.append((0, packed) if len(packed) <= len(raw) else (1, raw))
    return out


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

    @classmethod
    def deflate(cls, frames: np.ndarray, level: int = FRAME_DEFLATE_LEVEL) -> StoredFrames:
        """``frames`` (T, ...) deflated one frame a chunk, on the process's deflate threads."""
        frames = np.ascontiguousarray(frames)
        blocks = [frames[i : i + _FRAMES_PER_TASK] for i in range(0, len(frames), _FRAMES_PER_TASK)]
        done = _pool(os.getpid()).map(_deflate_block, blocks, [level] * len(blocks))
        return cls(frames.shape, frames.dtype, [c for block in done for c in block], level)

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
