"""robomimic-layout HDF5 backend: one short-lived, journaled file handle per write (see ``hdf5.journal``)."""

from __future__ import annotations

import functools
import os
import time
import uuid
from collections.abc import Iterator
from contextlib import ExitStack, closing, contextmanager
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..files import locking
from ..files.durability import fsync_path
from ..files.errors import damaged
from ..files.layout import NEXT_ID, PARTIAL_PREFIX, StoredDemo, demo_id_of, demo_name, from_stored, nest
from ..files.locking import locked_error
from . import journal
from .frames import FRAME_DEFLATE_LEVEL, StoredFrames

# Superblock v0 (no "file open for write" flag to clear after a crash); objects readable by HDF5 >= 1.10.
LIBVER = ("earliest", "v110")


def _open_read(path: Path) -> h5py.File:
    """Open for reading (after rolling back a killed writer); waits while a writer holds the lock."""
    deadline = time.monotonic() + locking.LOCK_WAIT_S
    journal.recover(path, locking.LOCK_WAIT_S)
    while True:
        try:
            return h5py.File(path, "r")
        except FileNotFoundError:
            raise FileNotFoundError(f"dataset {path} does not exist; check the path") from None
        except OSError as e:
            if "unable to lock file" not in str(e).lower():
                raise damaged(path, e) from None
            if time.monotonic() > deadline:
                raise locked_error(path, os.stat(path)) from None
            time.sleep(0.05)


@contextmanager
def _open_write(path: Path, fsync: bool) -> Iterator[h5py.File]:
    """Journaled read-write session under the writer lock: all of it lands on disk, or none of it (even on
    SIGKILL). The lock is taken first (it queues writers fairly, see ``files.locking.lock_exclusive``)."""
    if not path.exists():
        raise FileNotFoundError(f"dataset {path} does not exist; check the path")
    if not path.is_file():
        raise damaged(path, "not a file")
    with journal.journaled(path, locking.LOCK_WAIT_S, fsync) as fobj:
        try:
            h5py.File(path, "r", locking=False).close()  # same checks as readers; this session holds the lock
            f = h5py.File(fobj, "r+", libver=LIBVER)
        except OSError as e:
            raise damaged(path, e) from None
        with f:
            yield f


def _data(f: h5py.File, path: Path) -> h5py.Group:
    g = f.get("data")
    if not isinstance(g, h5py.Group):
        raise damaged(path, "no 'data' group")
    return g


def _committed_demo(data: h5py.Group, i: int) -> h5py.Group | None:
    """The committed demo ``i`` (a group with ``num_samples``), looked up by name; None when there is none."""
    g = data.get(demo_name(i))
    return g if isinstance(g, h5py.Group) and "num_samples" in g.attrs else None


def _committed(data: h5py.Group) -> dict[int, h5py.Group]:
    out = {}
    for name, g in data.items():
        i = demo_id_of(name)
        if i is not None and isinstance(g, h5py.Group) and "num_samples" in g.attrs:
            out[i] = g
    return out


_PLAIN_KINDS = "biuf"  # numeric and bool arrays: written through h5py's low-level API (``_write_plain``)


@functools.cache
def _plain_type(dtype: np.dtype) -> h5py.h5t.TypeID:
    return h5py.h5t.py_create(dtype, logical=1)


@functools.cache
def _plain_dcpl() -> h5py.h5p.PropDCID:
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)  # contiguous, no filters
    dcpl.set_obj_track_times(False)  # h5py's default (track_times=False)
    return dcpl


def _write_plain(g: h5py.Group, key: str, value: np.ndarray) -> None:
    """``g.create_dataset(key, data=value)`` for a non-empty numeric array (the same dataset: contiguous, no
    filters, no times) through ``h5py.h5d`` with its type and creation list made once: h5py's high-level
    ``create_dataset`` spends about as much Python on its argument handling as HDF5 spends creating the dataset
    (392 -> 191 us an array here), and a PickCube demo holds about 23 of them."""
    space = h5py.h5s.create_simple(value.shape)
    dset = h5py.h5d.create(g.id, key.encode(), _plain_type(value.dtype), space, dcpl=_plain_dcpl())
    dset.write(h5py.h5s.ALL, h5py.h5s.ALL, np.ascontiguousarray(value))


def _write_tree(g: h5py.Group, tree: dict[str, Any]) -> None:
    for key, value in tree.items():
        if isinstance(value, dict):
            _write_tree(g.create_group(key), value)
        elif isinstance(value, StoredFrames):  # another dataset's compressed frames, copied as they are
            value.write(g, key)
        elif value.ndim == 0 or value.size == 0:
            g.create_dataset(key, data=value)
        elif value.ndim >= 3:  # image frames of another type than _deflated's: h5py deflates them
            g.create_dataset(
                key, data=value, chunks=(1, *value.shape[1:]), compression="gzip", compression_opts=FRAME_DEFLATE_LEVEL
            )
        elif value.dtype.kind in _PLAIN_KINDS and key.isascii():  # state arrays: contiguous and uncompressed.
            # Physics floats barely compress (a PickCube demo: 162 KB raw, 183 KB as gzip-4 chunks, 176 KB
            # contiguous) and gzip doubled the append time (19 vs 9 ms/demo)
            _write_plain(g, key, value)
        else:  # other types and names: h5py's own conversions
            g.create_dataset(key, data=value)


def _deflated(tree: dict[str, Any]) -> dict[str, Any]:
    """``tree`` with its numeric image frames (T, H, W[, C]) deflated one frame a chunk (``StoredFrames.deflate``,
    on threads; docs/data.md: Image datasets), to be written as stored."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            out[key] = _deflated(value)
        elif isinstance(value, np.ndarray) and value.ndim >= 3 and value.size and value.dtype.kind in _PLAIN_KINDS:
            out[key] = StoredFrames.deflate(value)
        else:
            out[key] = value
    return out


def _read_array(dset: h5py.h5d.DatasetID) -> np.ndarray:
    """A dataset's whole array: numeric ones read into a new array through ``h5py.h5d`` (h5py's high-level
    ``Group.items`` and ``Dataset[()]`` cost more Python than HDF5 spends reading a PickCube demo's small
    arrays); 0-d, empty and other types through ``Dataset[()]``."""
    dtype = dset.dtype
    if dtype.kind not in _PLAIN_KINDS or not dset.shape or 0 in dset.shape:
        return np.asarray(h5py.Dataset(dset)[()])
    out = np.empty(dset.shape, dtype)
    dset.read(h5py.h5s.ALL, h5py.h5s.ALL, out)
    return out


def _read_node(gid: h5py.h5g.GroupID, stored_frames: bool = False) -> dict[str, Any]:
    out = {}
    for name in gid:  # link names in the group's name order, as h5py's Group.items()
        obj = h5py.h5o.open(gid, name)
        if isinstance(obj, h5py.h5g.GroupID):
            out[name.decode()] = _read_node(obj, stored_frames)
            continue
        frames = StoredFrames.read(h5py.Dataset(obj)) if stored_frames and len(obj.shape) >= 3 else None
        out[name.decode()] = _read_array(obj) if frames is None else frames
    return out


def _read_tree(g: h5py.Group) -> dict[str, Any]:
    return _read_node(g.id)


def _read_keys(g: h5py.Group, keys: tuple[str, ...] | None) -> dict[str, Any]:
    """``_read_tree`` of only the arrays named by ``keys`` ("actions", "obs/front_head_rgb"; all when None)."""
    if keys is None:
        return _read_tree(g)
    return nest({k: _read_array(g[k].id) for k in keys if isinstance(g.get(k), h5py.Dataset)})


def _attrs(obj: h5py.HLObject) -> dict[str, Any]:
    return {k: from_stored(v) for k, v in obj.attrs.items()}


def create(path: Path, root_attrs: dict[str, Any], fsync: bool) -> None:
    """Create an empty dataset atomically (temp file, then link into place; never overwrites)."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.partial")
    try:
        with h5py.File(tmp, "w-", libver=LIBVER) as f:
            f.create_group("data").attrs.update(root_attrs)
        if fsync:
            fsync_path(tmp)
        try:
            os.link(tmp, path)  # FileExistsError if someone else created it meanwhile
        except FileExistsError:
            raise
        except OSError:  # filesystem without hard links
            if path.exists():
                raise FileExistsError(path) from None
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    if fsync:
        fsync_path(path.parent)


def read_root(path: Path) -> dict[str, Any]:
    with _open_read(path) as f:
        return _attrs(_data(f, path))


def _counters(data: h5py.Group) -> tuple[int, int, int]:
    """(next demo id, total samples, num_demos) from the ``data`` attrs; a dataset written before
    ``next_demo_id`` existed is walked once (the caller stores the result)."""
    a = data.attrs
    if NEXT_ID in a:
        return int(a[NEXT_ID]), int(a.get("total", 0)), int(a.get("num_demos", 0))
    demos = _committed(data)
    return (max(demos, default=-1) + 1, sum(int(d.attrs["num_samples"]) for d in demos.values()), len(demos))


def _free_id(data: h5py.Group, i: int) -> int:
    """First id from ``i`` whose ``demo_<i>`` is not a committed demo; a stale group of that name (no
    ``num_samples``, or a ``_partial_`` one of an older writer) is removed. Looks up names, walks nothing."""
    while True:
        g = data.get(demo_name(i))
        if isinstance(g, h5py.Group) and "num_samples" in g.attrs:
            i += 1  # written by another tool without next_demo_id: never overwrite it
            continue
        for name in (demo_name(i), f"{PARTIAL_PREFIX}{demo_name(i)}"):
            if name in data:
                del data[name]
        return i


def append(path: Path, items: list[tuple[dict[str, Any], dict[str, Any], int]], fsync: bool) -> list[int]:
    """Write ``items`` ((tree, attrs, num_samples), ...) as ``data/demo_<i>`` and advance the ``data`` attrs
    ``next_demo_id`` / ``total`` / ``num_demos``, all in one journaled session: every demo lands or none. A
    ``StoredDemo`` tree (a demo of another HDF5 dataset) is copied with its attrs, then ``attrs`` update them.
    The cost does not depend on how many demos the dataset holds (no walk over them); image frames are deflated
    before the file is opened (``_deflated``)."""
    items = [(tree if isinstance(tree, StoredDemo) else _deflated(tree), attrs, n) for tree, attrs, n in items]
    with _open_write(path, fsync) as f, ExitStack() as sources:
        data = _data(f, path)
        next_id, total, count = _counters(data)
        ids = []
        opened: dict[Path, h5py.Group] = {}
        for tree, attrs, num_samples in items:
            next_id = _free_id(data, next_id)
            if isinstance(tree, StoredDemo):  # copied as stored (H5Ocopy: no decode, no Python per array)
                if tree.path not in opened:
                    opened[tree.path] = _data(sources.enter_context(_open_read(tree.path)), tree.path)
                source = _committed_demo(opened[tree.path], tree.demo_id)
                if source is None:
                    raise KeyError(tree.demo_id)
                data.copy(source, data, name=demo_name(next_id))
                g = data[demo_name(next_id)]
            else:
                g = data.create_group(demo_name(next_id))
                _write_tree(g, tree)
            g.attrs.update(attrs)
            g.attrs["num_samples"] = int(num_samples)
            ids.append(next_id)
            next_id, total = next_id + 1, total + int(num_samples)
        data.attrs.update({NEXT_ID: next_id, "total": total, "num_demos": count + len(ids)})
    return ids


def set_root_attrs(path: Path, attrs: dict[str, Any], fsync: bool = True) -> None:
    """Update ``data`` attrs in one journaled session."""
    with _open_write(path, fsync) as f:
        _data(f, path).attrs.update(attrs)


def info(path: Path) -> dict[str, Any]:
    with _open_read(path) as f:
        data = _data(f, path)
        demos = {
            i: {"num_samples": int(g.attrs["num_samples"]), "success": bool(g.attrs.get("success", False))}
            for i, g in _committed(data).items()
        }
        return {"root": _attrs(data), "demos": demos}


def read(path: Path, demo_id: int) -> tuple[dict[str, Any], dict[str, Any]]:
    with closing(read_many(path, [demo_id], None, attrs=True)) as one:  # closing: the file is closed on return
        return next(one)


def read_many(
    path: Path, demo_ids: list[int], keys: tuple[str, ...] | None, attrs: bool = False, stored_frames: bool = False
) -> Iterator[Any]:
    """Each demo's tree (with ``attrs``: and its attrs) through one open file, each demo looked up by name
    (``keys``: see ``_read_keys``; ``stored_frames``, with every key: image frames as their compressed chunks,
    ``StoredFrames``, where stored one a chunk). A demo not committed raises ``KeyError``."""
    with _open_read(path) as f:
        data = _data(f, path)
        for i in demo_ids:
            g = _committed_demo(data, i)
            if g is None:
                raise KeyError(i)
            try:
                tree = _read_node(g.id, stored_frames) if keys is None else _read_keys(g, keys)
                item = (tree, _attrs(g)) if attrs else tree
            except (OSError, RuntimeError) as e:
                raise damaged(path, f"{demo_name(i)}: {e}") from None
            yield item


def delete(path: Path, ids: list[int], fsync: bool = True) -> None:
    """Delete demos, drop them from the filter keys and refresh totals (space is reclaimed only by h5repack)."""
    with _open_write(path, fsync) as f:
        data = _data(f, path)
        next_id = _counters(data)[0]  # before deleting: ids are never reused
        for i in ids:
            del data[demo_name(i)]
        demos = _committed(data)
        data.attrs.update(
            {
                "total": sum(int(d.attrs["num_samples"]) for d in demos.values()),
                "num_demos": len(demos),
                NEXT_ID: next_id,
            }
        )
        gone = {demo_name(i) for i in ids}
        _write_masks(f, {k: [n for n in names if n not in gone] for k, names in _read_masks(f).items()})


def _read_masks(f: h5py.File) -> dict[str, list[str]]:
    g = f.get("mask")
    if not isinstance(g, h5py.Group):
        return {}
    return {
        k: [from_stored(n) for n in np.asarray(v[()]).reshape(-1)] for k, v in g.items() if isinstance(v, h5py.Dataset)
    }


def _write_masks(f: h5py.File, masks: dict[str, list[str]]) -> None:
    if not masks:
        return
    g = f.require_group("mask")
    for key, names in masks.items():
        if key in g:
            del g[key]
        g.create_dataset(key, data=np.array([n.encode() for n in names], dtype="S"))  # robomimic: byte strings


def read_masks(path: Path) -> dict[str, list[str]]:
    """robomimic filter keys: ``mask/<key>`` -> demo names."""
    with _open_read(path) as f:
        return _read_masks(f)


def set_masks(path: Path, masks: dict[str, list[str]], fsync: bool = True) -> None:
    """Write (or replace) the filter keys ``mask/<key>`` in one journaled session; other keys are kept."""
    with _open_write(path, fsync) as f:
        _write_masks(f, masks)
