"""``envs.frame_chunks``: per-row image frames in chunks that are only ever added (no grown copy holding the old and
the new frames at once), rows at different episode steps written and read back frame for frame."""

from __future__ import annotations

import torch

from newton_lab.envs.frame_chunks import IMAGE_CHUNK_STEPS, FrameChunks


def test_rows_at_different_steps_read_back_frame_for_frame_and_chunks_are_only_added():
    rows, shape, steps = 5, (3, 4, 3), 3 * IMAGE_CHUNK_STEPS + 7
    frames = FrameChunks("cam_rgb", rows, shape, torch.uint8, "cpu")
    dense = torch.zeros((rows, steps, *shape), dtype=torch.uint8)  # the reference: one full-length buffer
    start = torch.tensor([0, 5, 70, 130, 190])  # each row's episode starts that many steps into the run
    lengths = steps - start  # and runs to the run's end
    held, gen = [], torch.Generator().manual_seed(0)
    for step in range(steps):
        t = (step - start).clamp(min=0)  # a row not running yet writes step 0 until its episode starts
        shot = torch.randint(0, 255, (rows, *shape), dtype=torch.uint8, generator=gen)
        first, last = int(t.min()), int(t.max())
        frames.grow(last)
        frames.write(t, shot, first, last)
        dense[torch.arange(rows), t] = shot
        held.append(len(frames.chunks))
    assert held == sorted(held) and held[-1] == -(-steps // IMAGE_CHUNK_STEPS)  # added as the longest grew
    idx = torch.tensor([4, 1, 2])
    got = frames.gather(idx, steps)
    assert got.shape == (3, steps, *shape)
    for k, row in enumerate(idx.tolist()):
        assert torch.equal(got[k, : lengths[row]], dense[row, : lengths[row]]), row
    assert torch.equal(frames.gather(idx, 40), got[:, :40])
    longer = frames.gather(idx, frames.capacity + 5)  # past what was ever written: zero frames
    assert torch.equal(longer[:, :steps], got) and not longer[:, frames.capacity :].any()
    spare = sum(c[rows].numel() for c in frames.chunks)  # the spare row: one row's worth per chunk, nothing more
    assert sum(c.numel() for c in frames.chunks) == (rows + 1) * frames.capacity * 36 and spare == frames.capacity * 36
