"""zarr v3 backend (directory store): a demo is written under a temporary name, ``num_samples`` attr last,
and committed by renaming it to ``demo_<i>``; a ``demo_<i>`` without ``num_samples`` is a leftover.

Writers (append, delete, root attrs) hold the writer lock of both formats (``_common.lock_exclusive``)
on the store's root ``zarr.json``, a file written once at creation and never replaced, so they are
serialised and a demo id is allocated from what is committed. Readers take no lock.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import threading
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import zarr
from zarr.storage import LocalStore

from ._common import (PARTIAL_PREFIX, damaged, demo_id_of, demo_name, from_stored, fsync_path, lock_exclusive,
                      time_chunks, write_fault_point)


_io = threading.Condition()
_in_flight: dict[str, int] = {}  # store root -> writes under way
_refused: set[str] = set()  # "<root>/<prefix>": nodes of failed appends that take no more writes


class _Store(LocalStore):
    """LocalStore whose writes pass the fault-injection seam and can be drained after a failure.

    zarr does not cancel the sibling writes of a failed one; :func:`_drain` refuses further writes
    under a node and waits for those under way, so nothing lands after the node is removed.
    """

    async def _set(self, key: str, value: Any, exclusive: bool = False) -> None:
        root = str(self.root)
        with _io:
            if any(f"{root}/{key}".startswith(prefix) for prefix in _refused):
                raise OSError(errno.ECANCELED, f"write to {key} refused: its append failed")
            _in_flight[root] = _in_flight.get(root, 0) + 1
        try:
            write_fault_point()
            await super()._set(key, value, exclusive=exclusive)
        finally:
            with _io:
                _in_flight[root] -= 1
                _io.notify_all()


def _drain(path: Path, node: Path, timeout: float = 30.0) -> None:
    """Refuse further writes under ``node`` and wait for the writes to ``path`` under way."""
    root = str(path)
    with _io:
        _refused.add(f"{root}/{node.relative_to(path).as_posix()}/")
        _io.wait_for(lambda: not _in_flight.get(root), timeout=timeout)


def _root(path: Path, writable: bool = False) -> zarr.Group:
    if not path.is_dir():
        raise damaged(path, "not a zarr directory")
    try:
        store = _Store(path, read_only=not writable)
        return zarr.open_group(store=store, mode="r+" if writable else "r", zarr_format=3, use_consolidated=False)
    except Exception as e:  # noqa: BLE001 - any failure means "not a readable zarr v3 group"
        raise damaged(path, f"not a zarr v3 group: {type(e).__name__}: {e}") from None


def _data(root: zarr.Group, path: Path) -> zarr.Group:
    try:
        g = root["data"]
    except Exception:  # noqa: BLE001
        g = None
    if not isinstance(g, zarr.Group):
        raise damaged(path, "no 'data' group")
    return g


def _node_attrs(node_dir: Path) -> dict[str, Any] | None:
    """Attributes from a node's zarr.json, or None if missing/unreadable (uncommitted)."""
    try:
        meta = json.loads((node_dir / "zarr.json").read_bytes())
        return dict(meta.get("attributes") or {})
    except (OSError, ValueError, AttributeError):
        return None


def _scan(path: Path) -> tuple[dict[int, dict[str, Any]], list[Path]]:
    """(committed demo id -> attrs, leftovers of killed appends/deletes: dirs and ``*.partial`` files)."""
    committed, leftovers = {}, []
    for entry in os.scandir(path / "data"):
        if not entry.is_dir():
            if entry.name.endswith(".partial"):  # zarr's temp file of an interrupted metadata write
                leftovers.append(Path(entry.path))
            continue
        i = demo_id_of(entry.name)
        attrs = _node_attrs(Path(entry.path)) if i is not None else None
        if attrs is not None and "num_samples" in attrs:
            committed[i] = attrs
        elif i is not None or entry.name.startswith(PARTIAL_PREFIX):
            leftovers.append(Path(entry.path))
    return committed, leftovers


def _write_tree(g: zarr.Group, tree: dict[str, Any]) -> None:
    for key, value in tree.items():
        if isinstance(value, dict):
            _write_tree(g.create_group(key), value)
        else:
            chunks = time_chunks(value.shape, value.itemsize) if value.ndim else "auto"
            g.create_array(key, data=value, chunks=chunks)


def _read_tree(g: zarr.Group) -> dict[str, Any]:
    return {k: _read_tree(v) if isinstance(v, zarr.Group) else np.asarray(v[...]) for k, v in sorted(g.members())}


def _fsync_tree(top: Path) -> None:
    for dirpath, _, files in os.walk(top):
        for name in files:
            fsync_path(Path(dirpath, name))
        fsync_path(Path(dirpath))


def _totals(committed: dict[int, dict[str, Any]]) -> dict[str, int]:
    return {"total": sum(int(a["num_samples"]) for a in committed.values()), "num_demos": len(committed)}


def create(path: Path, root_attrs: dict[str, Any], fsync: bool) -> None:
    """Create an empty dataset atomically (temp directory renamed into place)."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.partial")
    try:
        root = zarr.open_group(store=LocalStore(tmp), mode="w-", zarr_format=3)
        root.create_group("data", attributes=root_attrs)
        if fsync:
            _fsync_tree(tmp)
        if path.exists():
            raise FileExistsError(path)
        try:
            os.rename(tmp, path)
        except OSError as e:  # created concurrently: rename onto a non-empty directory
            if e.errno in (errno.EEXIST, errno.ENOTEMPTY):
                raise FileExistsError(path) from None
            raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if fsync:
        fsync_path(path.parent)


def read_root(path: Path) -> dict[str, Any]:
    return {k: from_stored(v) for k, v in _data(_root(path), path).attrs.asdict().items()}


@contextmanager
def _locked(path: Path) -> Iterator[zarr.Group]:
    """Writer session: the store's ``data`` group, opened under the writer lock."""
    _root(path)  # same checks/errors as readers before touching anything
    try:
        fd = os.open(path / "zarr.json", os.O_RDWR)  # never written: opened for writing to lock it
    except OSError as e:
        raise damaged(path, f"zarr.json: {e.strerror}") from None
    try:
        lock_exclusive(fd, path)
        yield _data(_root(path, writable=True), path)
    finally:
        os.close(fd)  # releases the lock


def _remove(entry: Path) -> None:
    """Take a node out of the tree (atomic rename), then delete it."""
    trash = entry.with_name(f"{PARTIAL_PREFIX}deleted_{entry.name}_{uuid.uuid4().hex}")
    os.rename(entry, trash)
    shutil.rmtree(trash, ignore_errors=True)


def _clean(path: Path) -> dict[int, dict[str, Any]]:
    """Remove the leftovers of killed appends/deletes (under the lock); returns the committed demos."""
    committed, leftovers = _scan(path)
    for leftover in leftovers:
        if leftover.is_dir():
            shutil.rmtree(leftover, ignore_errors=True)
        else:
            leftover.unlink(missing_ok=True)
    return committed


def _write_demo(data: zarr.Group, tmp_dir: Path, tree: dict[str, Any], attrs: dict[str, Any],
                num_samples: int, fsync: bool) -> None:
    g = data.create_group(tmp_dir.name, attributes=attrs)
    _write_tree(g, tree)
    if fsync:
        _fsync_tree(tmp_dir)
    g.attrs["num_samples"] = int(num_samples)  # complete marker (atomic zarr.json replace)
    if fsync:
        fsync_path(tmp_dir / "zarr.json")
        fsync_path(tmp_dir)


def append(path: Path, tree: dict[str, Any], attrs: dict[str, Any], num_samples: int, fsync: bool) -> int:
    """Under the lock: write the demo under a name used once (``_partial_demo_<i>_<uuid>``) with
    ``num_samples`` last, rename it to ``demo_<i>`` (commit), then refresh totals.

    On any error the demo is taken out again (a failed append leaves the dataset as it was). zarr does
    not cancel the sibling writes of a failed one: they can only land in the unique temporary name.
    """
    with _locked(path) as data:
        committed = _clean(path)
        demo_id = max(committed, default=-1) + 1
        demo_dir = path / "data" / demo_name(demo_id)
        tmp_dir = demo_dir.with_name(f"{PARTIAL_PREFIX}{demo_dir.name}_{uuid.uuid4().hex}")
        totals_written = False
        try:
            _write_demo(data, tmp_dir, tree, attrs, num_samples, fsync)
            os.rename(tmp_dir, demo_dir)  # commit point
            if fsync:
                fsync_path(path / "data")
            data.attrs.update(_totals({**committed, demo_id: {"num_samples": int(num_samples)}}))
            totals_written = True
            if fsync:
                fsync_path(path / "data" / "zarr.json")
                fsync_path(path / "data")
        except BaseException:
            _drain(path, tmp_dir)
            _undo_append(data, (demo_dir, tmp_dir), committed, totals_written)
            raise
    return demo_id


def _undo_append(data: zarr.Group, dirs: tuple[Path, ...], committed: dict[int, dict[str, Any]],
                 totals: bool) -> None:
    try:
        for d in dirs:
            if d.exists():
                _remove(d)
        if totals:
            data.attrs.update(_totals(committed))
    except OSError:
        pass  # what is left is uncommitted or recounted: the next append cleans it


def set_root_attrs(path: Path, attrs: dict[str, Any], fsync: bool = True) -> None:
    """Update ``data`` attrs under the lock (zarr replaces ``zarr.json`` atomically)."""
    with _locked(path) as data:
        data.attrs.update(attrs)
        if fsync:
            fsync_path(path / "data" / "zarr.json")


def info(path: Path) -> dict[str, Any]:
    root = read_root(path)
    committed, _ = _scan(path)
    demos = {i: {"num_samples": int(a["num_samples"]), "success": bool(a.get("success", False))}
             for i, a in committed.items()}
    return {"root": root, "demos": demos}


def read(path: Path, demo_id: int) -> tuple[dict[str, Any], dict[str, Any]]:
    data = _data(_root(path), path)
    committed, _ = _scan(path)
    if demo_id not in committed:
        raise KeyError(demo_id)
    try:
        g = data[demo_name(demo_id)]
        return _read_tree(g), {k: from_stored(v) for k, v in g.attrs.asdict().items()}
    except Exception as e:  # noqa: BLE001
        raise damaged(path, f"{demo_name(demo_id)}: {type(e).__name__}: {e}") from None


def delete(path: Path, ids: list[int], fsync: bool = True) -> None:
    """Delete demos under the lock (atomic rename out of the tree, then rmtree), refresh totals and drop
    them from the filter keys."""
    with _locked(path) as data:
        for i in ids:
            _remove(path / "data" / demo_name(i))
        committed, _ = _scan(path)
        data.attrs.update(_totals(committed))
        if fsync:
            fsync_path(path / "data")
        gone = {demo_name(i) for i in ids}
        _write_masks(path, {k: [n for n in names if n not in gone] for k, names in read_masks(path).items()}, fsync)


# ----------------------------------------------------------------------------- filter keys (mask/<key>)
def read_masks(path: Path) -> dict[str, list[str]]:
    """robomimic filter keys: ``mask/<key>`` (vlen-utf8 string arrays) -> demo names."""
    root = _root(path)
    if not (path / "mask").is_dir():
        return {}
    out = {}
    for entry in sorted(os.scandir(path / "mask"), key=lambda e: e.name):
        if entry.is_dir() and not entry.name.startswith(PARTIAL_PREFIX) and _node_attrs(Path(entry.path)) is not None:
            try:
                out[entry.name] = [str(n) for n in np.asarray(root[f"mask/{entry.name}"][...]).reshape(-1)]
            except Exception as e:  # noqa: BLE001
                raise damaged(path, f"mask/{entry.name}: {type(e).__name__}: {e}") from None
    return out


def _write_masks(path: Path, masks: dict[str, list[str]], fsync: bool) -> None:
    """Each key is written under a temporary name, then renamed over the old one (under the writer lock)."""
    if not masks:
        return
    group = _root(path, writable=True).require_group("mask")
    mdir = path / "mask"
    for entry in mdir.iterdir():
        if entry.name.startswith(PARTIAL_PREFIX):  # leftovers of a killed session
            shutil.rmtree(entry, ignore_errors=True)
    for key, names in masks.items():
        tmp = f"{PARTIAL_PREFIX}{key}_{uuid.uuid4().hex}"
        group.create_array(tmp, data=np.array(names, dtype=np.dtypes.StringDType()))
        if fsync:
            _fsync_tree(mdir / tmp)
        if (mdir / key).exists():
            _remove(mdir / key)
        os.rename(mdir / tmp, mdir / key)
    if fsync:
        fsync_path(mdir)


def set_masks(path: Path, masks: dict[str, list[str]], fsync: bool = True) -> None:
    """Write (or replace) the filter keys ``mask/<key>`` under the writer lock; other keys are kept."""
    with _locked(path):
        _write_masks(path, masks, fsync)
