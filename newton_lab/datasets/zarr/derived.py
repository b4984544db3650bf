"""Arrays of a zarr pack stored once: a per-step array (rank 1 or 2: images are never compared, nor held whole at
once) whose bytes repeat another array of the same pack is written as a reference in the pack's index
(``zarr.packs``), and readers rebuild it. Lossless: bytes are compared, never values (-0.0 and 0.0 differ, NaNs
are compared as stored).

Index entries beside the ``rows`` of the plain layout (``zarr.packs`` module docstring):

- ``"same:<source>"``: the array equals ``<source>`` row for row; nothing is stored under its name.
- ``"next:<source>"``: each demo's rows are ``<source>``'s rows one step on, then one more row: the array stored
  under its name holds that last row of each demo (row ``k`` for demo ``k``), e.g. ``next_obs/<term>``, the
  observation after each step, against ``obs/<term>``, the one before it.

Why: a PickCube demo's ``next_obs/*`` are its ``obs/*`` one step on, and ``datagen/tcp_pose`` and
``datagen/object_poses/cube`` equal ``obs/tcp_pose`` and ``obs/cube_pose``: about a third of its stored bytes
(benchmarks history, the collection writer). Sources are arrays stored in full (a reference never points at
another reference); a reader that predates this layout fails on such an index (its rows are not numbers) instead of
returning wrong rows.
"""

from __future__ import annotations

from typing import Any

import numpy as np

SAME, NEXT = "same", "next"
PROBE_ROWS = 8
"""Rows compared first: most pairs differ there, and the full comparison is skipped."""


def _rows_bytes(value: np.ndarray) -> np.ndarray:
    """(rows, bytes of a row) uint8 view of a C-contiguous array."""
    return np.ascontiguousarray(value).reshape(len(value), -1).view(np.uint8)


def _order(key: str) -> tuple[int, str]:
    """Sources first: observations, then the rest, then ``datagen/*``, then ``next_obs/*``."""
    rank = 0 if key.startswith("obs/") else 3 if key.startswith("next_obs/") else 2 if key.startswith("datagen/") else 1
    return rank, key


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    ra, rb = _rows_bytes(a), _rows_bytes(b)
    return np.array_equal(ra[:PROBE_ROWS], rb[:PROBE_ROWS]) and np.array_equal(ra, rb)


def _next(source: np.ndarray, b: np.ndarray, ends: np.ndarray) -> bool:
    """Every demo's rows of ``b`` but its last equal ``source``'s rows one step on (``ends``: each demo's end row)."""
    if source.dtype != b.dtype or source.shape != b.shape or len(b) < 2:
        return False
    rs, rb = _rows_bytes(source), _rows_bytes(b)
    probe = min(PROBE_ROWS, int(ends[0]) - 1)
    if probe > 0 and not np.array_equal(rb[:probe], rs[1 : probe + 1]):
        return False
    shifted = rb[:-1].copy()
    shifted[ends[:-1] - 1] = rs[ends[:-1]]  # a demo's last row is stored apart: left out of the comparison
    return np.array_equal(shifted, rs[1:])  # one contiguous comparison (a per-row reduction costs ten times more)


def derive(values: dict[str, np.ndarray], layout: dict[str, int | None], counts: list[int]) -> dict[str, Any]:
    """The pack index's ``arrays``: ``layout`` with each per-step array that repeats a stored one replaced by its
    reference (``values``: every array of the pack, demos one after another; ``counts``: each demo's steps)."""
    ends = np.cumsum(counts)
    out: dict[str, Any] = dict(layout)
    stored: list[str] = []
    for key in sorted((k for k, rows in layout.items() if rows is None), key=_order):
        value = values[key]
        ref = next((f"{SAME}:{other}" for other in stored if _same(values[other], value)), None)
        source = "obs/" + key[len("next_obs/") :] if key.startswith("next_obs/") else None
        if ref is None and source in stored and _next(values[source], value, ends):
            ref = f"{NEXT}:{source}"
        if ref is None:
            stored.append(key)
        else:
            out[key] = ref
    return out


def stored_value(entry: Any, value: np.ndarray, counts: list[int]) -> np.ndarray | None:
    """What is stored under an array's name: the array itself (plain layout), each demo's last row (``next``), or
    None (``same``: nothing)."""
    if not isinstance(entry, str):
        return value
    kind = entry.partition(":")[0]
    return value[np.cumsum(counts) - 1] if kind == NEXT else None


def rebuild(entry: str, source: np.ndarray, last: np.ndarray | None) -> np.ndarray:
    """One demo's rows of a referenced array from its source's rows (and, for ``next``, its stored last row)."""
    kind, _, _ = entry.partition(":")
    if kind == SAME:
        return source
    if kind == NEXT and last is not None:
        return np.concatenate([source[1:], last])
    raise ValueError(f"pack array reference {entry!r} is not one this version reads")


def rebuild_needs_last(entry: str) -> bool:
    """Whether a reference has rows of its own stored (``next``: each demo's last row)."""
    return entry.partition(":")[0] == NEXT


def source_of(entry: Any) -> str | None:
    """The source array's name of a reference entry, None for a plain one."""
    return entry.partition(":")[2] if isinstance(entry, str) else None
