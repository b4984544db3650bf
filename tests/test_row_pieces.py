"""``RowPieces``: arrays joined along time without copying, as the writer process holds image frames in its ring."""

from __future__ import annotations

import numpy as np
import pytest

from newton_lab.datasets.files.row_pieces import RowPieces


def test_row_pieces_read_as_the_joined_array():
    rng = np.random.default_rng(0)
    pieces = [rng.integers(0, 255, (n, 4, 3), dtype=np.uint8) for n in (5, 1, 7, 3)]
    joined = np.concatenate(pieces)
    rp = RowPieces(pieces[:2]).join([RowPieces(pieces[:2]), RowPieces(pieces[2:])])
    assert rp.shape == joined.shape and rp.dtype == joined.dtype and rp.ndim == 3 and len(rp) == 16
    assert rp.nbytes == joined.nbytes and rp.size == joined.size and rp.itemsize == 1
    for a in range(17):
        for b in range(a, 18):
            np.testing.assert_array_equal(rp.rows(a, b), joined[a:b])
    np.testing.assert_array_equal(rp[3:11], joined[3:11])
    np.testing.assert_array_equal(rp[::2], joined[::2])  # anything but a plain slice indexes the joined array
    np.testing.assert_array_equal(np.asarray(rp), joined)
    assert np.shares_memory(rp.rows(6, 12), pieces[2])  # one piece holds them: a view, nothing copied


def test_row_pieces_refuse_pieces_that_differ():
    with pytest.raises(ValueError, match="pieces differ"):
        RowPieces([np.zeros((2, 3), np.uint8), np.zeros((2, 4), np.uint8)])
    with pytest.raises(ValueError, match="at least one piece"):
        RowPieces([])
