"""A pack stores an array as a reference to another (``zarr.derived``) only where every byte it stands for repeats:
the next-step reference leaves out exactly each demo's last row, and nothing else. Fast, no physics."""

from __future__ import annotations

import numpy as np
import pytest

from newton_lab.datasets.zarr.derived import NEXT, derive, rebuild

COUNTS = [1, 5, 2, 9, 1, 4]  # demos of one step too: their only row is their last


def _obs_and_next(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``obs`` of the demos joined along time, and ``next_obs``: each demo's rows one step on, then a last row of
    its own."""
    rng = np.random.default_rng(seed)
    obs, nxt = [], []
    for n in COUNTS:
        rows = rng.standard_normal((n + 1, 3)).astype(np.float32)
        obs.append(rows[:-1])
        nxt.append(rows[1:])
    return np.concatenate(obs), np.concatenate(nxt)


def _entry(obs: np.ndarray, nxt: np.ndarray):
    layout = {"obs/x": None, "next_obs/x": None}
    return derive({"obs/x": obs, "next_obs/x": nxt}, layout, COUNTS)["next_obs/x"]


def test_next_obs_is_a_reference_and_rebuilds_every_demo_byte_for_byte():
    obs, nxt = _obs_and_next(0)
    entry = _entry(obs, nxt)
    assert entry == f"{NEXT}:obs/x"
    starts = np.cumsum([0] + COUNTS[:-1])
    for start, n in zip(starts, COUNTS):
        last = nxt[start + n - 1 : start + n]
        assert rebuild(entry, obs[start : start + n], last).tobytes() == nxt[start : start + n].tobytes()


@pytest.mark.parametrize("row", range(sum(COUNTS)))
def test_one_changed_byte_in_any_row_but_a_demos_last_keeps_the_array_stored_in_full(row):
    """Every row of ``next_obs`` that the reference stands for is compared: a change in the first row of a later
    demo, in a demo's middle, or just before a demo's end stores the array in full; a change in a demo's last row
    (stored apart, under the array's own name) keeps the reference."""
    obs, nxt = _obs_and_next(1)
    nxt = nxt.copy()
    nxt.view(np.uint8)[row, 5] ^= 1
    last_rows = set((np.cumsum(COUNTS) - 1).tolist())
    assert _entry(obs, nxt) == (f"{NEXT}:obs/x" if row in last_rows else None)


def test_negative_zero_is_not_zero():
    obs, nxt = _obs_and_next(2)
    obs[3, 0], nxt[2, 0] = 0.0, -0.0  # row 2 of next_obs stands for row 3 of obs: equal values, other bytes
    assert _entry(obs, nxt) is None
