"""Per-row image frames of the running episodes (``envs.recorder``), on the env's device in chunks of
``IMAGE_CHUNK_STEPS`` steps that are added as the longest running episode grows.

Why chunks, and not one buffer grown by copying it into a longer one: while it is copied, the old and the new buffer
are both held, so the peak was about twice the frames. Two-camera PickToShelf at 4096 rows holds ~87 GB of 96x72 RGB
frames at its longest episodes (512 steps): a ~163 GB peak, past an H200's 141 GB; chunks are only ever added, so
the peak is the frames. A step writes each row's frame into the chunk of that row's episode step: one indexed write
per chunk that some row is in, the rows in other chunks sent to a spare row that nothing reads (no device-to-host
sync to sort the rows out).
"""

from __future__ import annotations

import math

import torch

IMAGE_CHUNK_STEPS = 64
"""Steps of one chunk of per-row image frames (the frames' time capacity is a multiple of it)."""


class FrameChunks:
    """One image term's frames of ``rows`` running episodes: ``write`` stores each row's frame at its episode step,
    ``gather`` reads finished rows' frames back as one ``(rows, steps, ...)`` tensor."""

    def __init__(self, name: str, rows: int, shape: tuple[int, ...], dtype: torch.dtype, device) -> None:
        self.name, self.rows, self.shape, self.dtype, self.device = name, rows, tuple(shape), dtype, device
        self.chunks: list[torch.Tensor] = []
        """Each ``(rows + 1, IMAGE_CHUNK_STEPS, *shape)``: steps ``k * IMAGE_CHUNK_STEPS ..`` of chunk ``k``; the
        last row is the spare one."""
        self._rows = torch.arange(rows, device=device)
        self._spare = torch.full((rows,), rows, device=device)

    @property
    def capacity(self) -> int:
        """Episode steps the chunks hold."""
        return len(self.chunks) * IMAGE_CHUNK_STEPS

    def grow(self, last: int) -> None:
        """Add chunks until step ``last`` is held; a one-line ``MemoryError`` naming the fixes when the device has no
        room."""
        while self.capacity <= last:
            try:
                chunk = torch.zeros(
                    (self.rows + 1, IMAGE_CHUNK_STEPS, *self.shape), dtype=self.dtype, device=self.device
                )
            except (torch.OutOfMemoryError, RuntimeError) as e:  # CUDA: OutOfMemoryError; CPU: RuntimeError
                if not isinstance(e, torch.OutOfMemoryError) and "allocate" not in str(e):
                    raise
                steps = self.capacity + IMAGE_CHUNK_STEPS
                itemsize = torch.empty((), dtype=self.dtype).element_size()
                need = self.rows * steps * math.prod(self.shape) * itemsize / 2**30
                raise MemoryError(
                    f"recording {self.name} of {self.rows} rows for {steps} steps needs {need:.1f} GiB on "
                    f"{self.device}, more than is free; record fewer rows (--num-envs), smaller frames "
                    f"(--cameras name=WxH) or no images (--cameras none)"
                ) from None
            self.chunks.append(chunk)

    def write(self, t: torch.Tensor, frames: torch.Tensor, first: int, last: int) -> None:
        """Store ``frames`` (rows, ...) of every row at its episode step ``t`` (rows,), whose least and greatest are
        ``first`` and ``last`` (held: :meth:`grow`)."""
        chunk, step = t // IMAGE_CHUNK_STEPS, t % IMAGE_CHUNK_STEPS
        for k in range(first // IMAGE_CHUNK_STEPS, last // IMAGE_CHUNK_STEPS + 1):
            self.chunks[k][torch.where(chunk == k, self._rows, self._spare), step] = frames

    def gather(self, idx: torch.Tensor, span: int) -> torch.Tensor:
        """``(len(idx), span, *shape)``: the first ``span`` steps of the rows ``idx`` (zero frames past what was
        ever written)."""
        out = torch.empty((len(idx), span, *self.shape), dtype=self.dtype, device=self.device)
        for k, chunk in enumerate(self.chunks):
            a = k * IMAGE_CHUNK_STEPS
            if a >= span:
                break
            b = min(span, a + IMAGE_CHUNK_STEPS)
            out[:, a:b] = chunk[idx, : b - a]
        if self.capacity < span:
            out[:, self.capacity :] = 0
        return out
