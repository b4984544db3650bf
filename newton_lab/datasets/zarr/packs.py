"""Packed zarr demos: a large batch of demos written as a few groups ``data/pack_<first id>`` whose arrays hold the
demos one after another along time, instead of one ``data/demo_<i>`` group (~80 files and folders) per demo.

Why: on one ext4 disk the per-demo layout made file creation, not physics, bound collection (two GPUs writing
330 k files per 4096 demos each thrashed the volume), and a filesystem's inodes ran out long before its bytes. A
pack of 512 PickCube demos is ~150 files. The logical layout is unchanged: readers (``zarr.store.read_many``) map a
demo id to its pack and rows and return the same tree a ``demo_<i>`` group gives. A per-step array whose bytes repeat
another of the pack (``next_obs/<term>``: ``obs/<term>`` one step on) is stored once, as a reference in the index
(``zarr.derived``), and rebuilt when read.

A pack group's attrs hold its index, ``{"pack": {"arrays": {path: rows}, "demos": {id: [k, start, attrs]}}}``:
``rows`` is ``null`` for arrays with one row per step (demo ``k`` holds rows ``start .. start + num_samples``),
``c >= 1`` for arrays of ``c`` rows per demo (rows ``k*c .. (k+1)*c``, e.g. ``initial_state``), ``0`` for one scalar
per demo (row ``k``), or a reference ``"same:<array>"`` / ``"next:<array>"`` (``zarr.derived``). The ids of a pack
are ``first .. first + n - 1`` when written; a delete drops ids from the index (the rows stay until the pack is
empty, then the pack goes). Arrays are stored as ``zarr.nodes`` stores a demo's (same codecs, ~1 MB time chunks,
image frames too), so zarr-python reads them as well (a referenced array: its source, and for ``next``
each demo's last row under its own name).
"""

from __future__ import annotations

import json
import math
import os
import re
import uuid
from bisect import bisect_right
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..files.durability import fsync_path
from ..files.layout import StoredDemo, demo_name, nest
from .derived import derive, rebuild, rebuild_needs_last, source_of, stored_value
from .nodes import (
    DECODER,
    chunk_grid,
    chunk_shape,
    node_meta,
    plain_dtype,
    write_array,
    write_demo,
    write_file,
    write_group,
)

PACK_RE = re.compile(r"^pack_(\d+)$")
CACHE_BYTES = 64 << 20
"""Decoded chunks a reader keeps (demos read one after another share their packs' chunks)."""


def pack_name(first: int) -> str:
    return f"pack_{int(first)}"


def pack_first_of(name: str) -> int | None:
    """First demo id of a pack folder name, or None for anything else."""
    m = PACK_RE.match(name)
    return int(m.group(1)) if m else None


class PackJob(NamedTuple):
    """One pack to write: its folder, per demo its id, attrs (``num_samples`` included) and arrays by path
    (``{"obs/x": array}``), and the pack's ``layout``; or, instead of the per-demo arrays, every array already
    joined (``joined``: a ``columns.DemoBlock``'s ``arrays()``)."""

    node: Path
    ids: list[int]
    attrs: list[dict[str, Any]]
    flats: list[dict[str, np.ndarray]] | None
    layout: dict[str, int | None]
    joined: dict[str, np.ndarray] | None = None


def _flat(tree: dict[str, Any], prefix: str = "") -> dict[str, np.ndarray] | None:
    """``{"obs/x": array, ...}`` of a demo tree; None if it has an empty group (a pack keeps no groups alone)."""
    out: dict[str, np.ndarray] = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            sub = _flat(value, f"{prefix}{key}/")
            if not sub:
                return None
            out.update(sub)
        else:
            out[f"{prefix}{key}"] = np.asarray(value)
    return out


def _groups(keys) -> list[str]:
    """Every group above the array paths ``keys`` ("a/b/c" -> "a", "a/b"), parents first."""
    return sorted({key.rsplit("/", i)[0] for key in keys for i in range(1, key.count("/") + 1)})


def layout(items: list[tuple[Any, dict[str, Any], int]]) -> tuple[dict[str, int | None], list] | None:
    """(the pack index's ``arrays``, see the module docstring, shared by every (tree, attrs, num_samples) of a batch;
    each tree's arrays by path), or None when the batch cannot be one pack layout (copies of stored demos, keys,
    dtypes or trailing shapes differ, rows that follow neither the steps nor a constant)."""
    if any(isinstance(tree, StoredDemo) for tree, _, _ in items):
        return None
    flats = [_flat(tree) for tree, _, _ in items]
    if any(f is None or f.keys() != flats[0].keys() for f in flats):
        return None
    out: dict[str, int | None] = {}
    for key, first in flats[0].items():
        values = [f[key] for f in flats]
        if any(v.dtype != first.dtype or v.shape[1:] != first.shape[1:] or v.ndim != first.ndim for v in values):
            return None
        if first.ndim == 0:
            out[key] = 0
        elif all(v.shape[0] == n for v, (_, _, n) in zip(values, items)):
            out[key] = None
        elif first.shape[0] >= 1 and all(v.shape[0] == first.shape[0] for v in values):
            out[key] = first.shape[0]
        else:
            return None
    return out, flats


def batch_jobs(stage: Path, ids: list[int], items: list[tuple[Any, dict[str, Any], int]], pack_min_batch: int) -> list:
    """The write jobs of a batch (``(tree, attrs, num_samples)`` per demo id): one ``PackJob`` of all of them when
    the batch has ``pack_min_batch`` demos or more (``ZarrWriteSettings``) of one layout; else one
    ``(folder, attrs, tree)`` per demo. Folders go under ``stage``."""
    attrs = [{**a, "num_samples": int(n)} for _, a, n in items]
    found = layout(items) if len(items) >= pack_min_batch else None
    if found is None:
        return [(stage / demo_name(i), a, tree) for i, a, (tree, _, _) in zip(ids, attrs, items)]
    shared, flats = found
    return [PackJob(stage / pack_name(ids[0]), ids, attrs, flats, shared)]


def write_pack(job: PackJob, fallback: Callable[[str, np.ndarray], None], tasks: Any = None) -> None:
    """The pack group ``job.node`` with its index and every array of its demos one after another;
    ``fallback(relpath, value)`` writes an array ``zarr.nodes`` does not. Not durable until the caller syncs. With
    ``tasks`` (anything with ``append``) each chunk's encoding and file go there as calls (``write_array``)."""
    counts = [int(a["num_samples"]) for a in job.attrs]
    starts = np.cumsum([0] + counts[:-1]).tolist()
    demos = {str(i): [k, s, a] for k, (i, s, a) in enumerate(zip(job.ids, starts, job.attrs))}

    def joined(key: str) -> np.ndarray:
        if job.joined is not None:
            return job.joined[key]
        parts = [f[key] for f in job.flats]
        return np.stack(parts) if job.layout[key] == 0 else np.concatenate(parts)

    def ndim(key: str) -> int:  # of one demo's array
        return job.joined[key].ndim if job.joined is not None else job.flats[0][key].ndim

    # arrays that repeat another become a reference (``zarr.derived``); images are never compared (nor held at once)
    values = {key: joined(key) for key in job.layout if ndim(key) < 3}
    found = derive(values, {k: rows for k, rows in job.layout.items() if k in values}, counts)
    arrays = {key: found.get(key, rows) for key, rows in job.layout.items()}
    write_group(job.node, {"pack": {"arrays": arrays, "demos": demos}})
    for group in _groups(job.layout):
        write_group(f"{job.node}/{group}", {})
    for key, entry in arrays.items():
        value = stored_value(entry, values.pop(key) if key in values else joined(key), counts)
        if value is not None and not write_array(f"{job.node}/{key}", value, tasks):
            fallback(key, np.asarray(value))  # image frames held as views (``RowPieces``) joined for zarr-python


def write_job(
    job: PackJob | tuple[Path, dict[str, Any], dict[str, Any]],
    fallback: Callable[[Path, str, np.ndarray], None],
    tasks: Any = None,
) -> None:
    """Write a pack, or one demo group ``(folder, attrs, tree)``; ``fallback(node, relpath, value)`` and a pack's
    ``tasks`` as above."""
    if isinstance(job, PackJob):
        write_pack(job, fallback=lambda rel, value: fallback(job.node, rel, value), tasks=tasks)
    else:
        node, attrs, tree = job
        write_demo(node, attrs, tree, fallback=lambda rel, value: fallback(node, rel, value))


def read_index(node: str | Path) -> dict[str, Any] | None:
    """A pack's index (``arrays``, ``demos``), or None if its ``zarr.json`` is missing or not a pack's."""
    meta = node_meta(os.fspath(node))
    pack = (meta or {}).get("attributes", {}).get("pack")
    return pack if isinstance(pack, dict) and "demos" in pack and "arrays" in pack else None


def drop(node: Path, ids: list[int], fsync: bool) -> int:
    """Take ``ids`` out of the pack's index (its ``zarr.json`` replaced atomically); returns the demos left."""
    meta = json.loads((node / "zarr.json").read_bytes())
    demos = meta["attributes"]["pack"]["demos"]
    for i in ids:
        demos.pop(str(i), None)
    if demos:
        tmp = node / f".zarr.json.{uuid.uuid4().hex}"
        write_file(os.fspath(tmp), json.dumps(meta, indent=2).encode())
        if fsync:
            fsync_path(tmp)
        os.replace(tmp, node / "zarr.json")
        if fsync:
            fsync_path(node)
    return len(demos)


def inodes_of_pack(tree: dict[str, Any], demos: int) -> int:
    """Files and folders of a pack of ``demos`` demos shaped like ``tree`` (rows scaled by ``demos``)."""
    flat = _flat(tree) or {}
    count = 2 + 2 * len(_groups(flat))
    for value in flat.values():
        shape = (demos,) if value.ndim == 0 else (demos * value.shape[0], *value.shape[1:])
        count += 2 + (math.prod(chunk_grid(shape, chunk_shape(shape, value.itemsize))) if value.size else 0)
    return count


class PackReader:
    """Demos read out of the committed packs of one dataset (``data`` folder ``data_dir``, packs whose first id is
    below ``limit``); ``fallback(relpath, start, stop)`` reads rows of an array that is not of the plain layout
    (with zarr-python; None: ``locate`` only). Pack list, indexes, array metadata and recent chunks are kept while
    it lives."""

    def __init__(
        self, data_dir: Path, limit: int | None, fallback: Callable[[str, int, int], np.ndarray] | None
    ) -> None:
        self._dir, self._limit, self._fallback = data_dir, limit, fallback
        self._firsts: list[int] | None = None
        self._indexes: dict[int, dict[str, Any] | None] = {}
        self._metas: dict[str, dict[str, Any] | None] = {}
        self._cache: OrderedDict[tuple[str, int], np.ndarray] = OrderedDict()
        self._cached = 0

    def _packs(self) -> list[int]:
        if self._firsts is None:
            firsts = (pack_first_of(e.name) for e in os.scandir(self._dir))
            self._firsts = sorted(f for f in firsts if f is not None and (self._limit is None or f < self._limit))
        return self._firsts

    def locate(self, demo_id: int) -> tuple[str, int, int, dict[str, Any], dict[str, Any]] | None:
        """(pack name, k, start, attrs, arrays) of a committed packed demo, or None."""
        firsts = self._packs()
        j = bisect_right(firsts, demo_id) - 1
        if j < 0:
            return None
        first = firsts[j]
        if first not in self._indexes:
            self._indexes[first] = read_index(self._dir / pack_name(first))
        index = self._indexes[first]
        entry = None if index is None else index["demos"].get(str(demo_id))
        if entry is None:
            return None
        k, start, attrs = entry
        return pack_name(first), int(k), int(start), attrs, index["arrays"]

    def read(
        self, found: tuple[str, int, int, dict[str, Any], dict[str, Any]], keys: tuple[str, ...] | None
    ) -> dict[str, Any]:
        """The demo's tree (only ``keys`` when given; a key it lacks is left out), nested and sorted."""
        name, k, start, attrs, arrays = found
        flat = {}
        for key in sorted(arrays if keys is None else [key for key in keys if key in arrays]):
            rows, source = arrays[key], source_of(arrays[key])
            if source is not None:  # stored once, under ``source`` (``zarr.derived``)
                last = self._rows(f"{name}/{key}", k, k + 1) if rebuild_needs_last(rows) else None
                flat[key] = rebuild(rows, self._array(name, source, arrays[source], k, start, attrs), last)
                continue
            flat[key] = self._array(name, key, rows, k, start, attrs)
        return nest(flat)

    def _array(self, name: str, key: str, rows: int | None, k: int, start: int, attrs: dict[str, Any]) -> np.ndarray:
        """Demo ``k``'s rows of the stored array ``key`` (``rows`` from the index)."""
        a, b = (
            (start, start + int(attrs["num_samples"]))
            if rows is None
            else (k, k + 1)
            if rows == 0
            else (k * rows, (k + 1) * rows)
        )
        value = self._rows(f"{name}/{key}", a, b)
        return value.reshape(value.shape[1:]) if rows == 0 else value

    def _rows(self, rel: str, a: int, b: int) -> np.ndarray:
        node = os.fspath(self._dir / rel)
        if node not in self._metas:
            self._metas[node] = node_meta(node)
        meta = self._metas[node]
        dtype = None if meta is None else plain_dtype(meta)
        if dtype is None or tuple(meta["chunk_grid"]["configuration"]["chunk_shape"][1:]) != tuple(meta["shape"][1:]):
            return np.asarray(self._fallback(rel, a, b))
        shape, c = tuple(meta["shape"]), int(meta["chunk_grid"]["configuration"]["chunk_shape"][0])
        out = np.empty((b - a, *shape[1:]), dtype)
        for ci in range(a // c, (b - 1) // c + 1):
            block = self._chunk(node, ci, (c, *shape[1:]), dtype, meta["fill_value"])
            lo, hi = max(a, ci * c), min(b, (ci + 1) * c)
            out[lo - a : hi - a] = block[lo - ci * c : hi - ci * c]
        return out

    def _chunk(self, node: str, ci: int, shape: tuple[int, ...], dtype: np.dtype, fill: Any) -> np.ndarray:
        key = (node, ci)
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        try:
            with open(f"{node}/c.{'.'.join([str(ci)] + ['0'] * (len(shape) - 1))}", "rb") as f:
                block = np.frombuffer(DECODER.decode(f.read()), dtype).reshape(shape)
        except FileNotFoundError:  # zarr leaves out a chunk that holds only the fill value
            block = np.full(shape, fill, dtype)
        self._cache[key] = block
        self._cached += block.nbytes
        while self._cached > CACHE_BYTES and len(self._cache) > 1:
            self._cached -= self._cache.popitem(last=False)[1].nbytes
        return block
