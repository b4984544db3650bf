"""zarr v3 backend (directory store): a batch of demos is written under a staging folder, renamed to
``demo_<i>`` and committed by advancing the ``data`` attr ``next_demo_id``; a ``demo_<i>`` without
``num_samples`` or with ``i >= next_demo_id`` is a leftover (readers skip it, the next append removes it).

Writers (append, delete, root attrs) hold the writer lock of both formats (``_common.lock_exclusive``)
on the store's root ``zarr.json``, a file written once at creation and never replaced, so they are
serialised and demo ids come from ``next_demo_id``. Readers take no lock.
"""

from __future__ import annotations

import errno
import functools
import json
import os
import shutil
import threading
import uuid
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor, wait
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import zarr
from zarr.storage import LocalStore

from ._common import (NEXT_ID, PARTIAL_PREFIX, damaged, demo_id_of, demo_name, fault_injected, from_stored,
                      fsync_path, lock_exclusive, sync_tree, write_fault_point)
from .zarr_nodes import array_kwargs, read_tree, write_demo, write_group
from . import zarr_workers

STAGING = f"{PARTIAL_PREFIX}batches"  # data/_partial_batches/<uuid>/demo_<i>: a batch being written


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


def _scan(path: Path, limit: int | None = None) -> tuple[dict[int, dict[str, Any]], list[Path]]:
    """(committed demo id -> attrs, leftovers of killed appends/deletes: dirs and ``*.partial`` files). With
    ``limit`` (the ``next_demo_id`` attr) a ``demo_<i>``, ``i >= limit``, is a leftover of a killed batch."""
    committed, leftovers = {}, []
    for entry in os.scandir(path / "data"):
        if not entry.is_dir():
            if entry.name.endswith(".partial"):  # zarr's temp file of an interrupted metadata write
                leftovers.append(Path(entry.path))
            continue
        i = demo_id_of(entry.name)
        attrs = _node_attrs(Path(entry.path)) if i is not None else None
        if attrs is not None and "num_samples" in attrs and (limit is None or i < int(limit)):
            committed[i] = attrs
        elif i is not None or entry.name.startswith(PARTIAL_PREFIX):
            leftovers.append(Path(entry.path))
    return committed, leftovers


WRITE_THREADS = int(os.environ.get("NEWTON_LAB_ZARR_WRITE_THREADS", "4"))
"""Threads writing a small batch's demos (file creation waits on the filesystem, not on the GIL)."""
def _write_job(path: Path, job: tuple[Path, dict[str, Any], dict[str, Any]]) -> None:
    node, attrs, tree = job
    write_demo(node, attrs, tree, fallback=functools.partial(_write_with_zarr, path, node))


def _parallel(path: Path, jobs: list) -> None:
    """Write every (demo folder, attrs, tree) of ``jobs``: a large batch on the writer processes, a small one (or
    any under an injected test fault, which lives in this process) on ``WRITE_THREADS`` threads. Returns when
    every writer stopped; raises the first error."""
    if len(jobs) >= zarr_workers.PROCESS_MIN_BATCH and zarr_workers.WRITE_PROCESSES >= 1 and not fault_injected():
        try:
            leftovers = zarr_workers.shared().write(jobs)
        except zarr_workers.WriterDied as e:
            raise RuntimeError(f"{e} to {path}; none of the batch was committed") from None
        for node, rel, value in leftovers:
            _write_with_zarr(path, node, rel, value)
    elif len(jobs) < 2 or WRITE_THREADS < 2:
        for job in jobs:
            _write_job(path, job)
    else:
        with ThreadPoolExecutor(min(WRITE_THREADS, len(jobs)), thread_name_prefix="zarr-write") as pool:
            futures = [pool.submit(_write_job, path, job) for job in jobs]
            wait(futures)  # nothing may still be writing when the caller removes the staging folder
        for future in futures:
            future.result()


def _write_with_zarr(path: Path, demo: Path, rel: str, value: np.ndarray) -> None:
    """One array of a staged demo written by zarr-python (what ``zarr_nodes`` leaves to it)."""
    parent, _, name = rel.rpartition("/")
    node = (demo / parent).relative_to(path).as_posix()
    group = zarr.open_group(store=_Store(path), path=node, mode="r+", zarr_format=3)
    group.create_array(name, data=value, **array_kwargs(value))


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


def _counters(data: zarr.Group, path: Path) -> tuple[int, int, int]:
    """(next demo id, total samples, num_demos) from the ``data`` attrs (under the lock). A dataset written
    before ``next_demo_id`` existed is scanned once (and its leftovers removed); the caller stores the result."""
    a = data.attrs.asdict()
    if NEXT_ID in a:
        return int(a[NEXT_ID]), int(a.get("total", 0)), int(a.get("num_demos", 0))
    committed = _clean(path)
    return max(committed, default=-1) + 1, _totals(committed)["total"], len(committed)


def _clean_tail(path: Path, next_id: int) -> None:
    """Remove what a killed batch left (under the lock): its staging folder and the ``demo_<i>`` it had
    renamed into place, ``i >= next_id`` (never committed: readers ignore them). Looks only at those names."""
    staging = path / "data" / STAGING
    if staging.exists():
        shutil.rmtree(staging, ignore_errors=True)
    while (path / "data" / demo_name(next_id)).exists():
        _remove(path / "data" / demo_name(next_id))
        next_id += 1


def _commit(data: zarr.Group, counters: dict[str, int]) -> None:
    """The commit point of a batch: ``data/zarr.json`` (replaced atomically) gets the new ``next_demo_id``."""
    data.attrs.update(counters)


def append(path: Path, items: list[tuple[dict[str, Any], dict[str, Any], int]], fsync: bool) -> list[int]:
    """Under the lock, write ``items`` ((tree, attrs, num_samples), ...) as one batch: each demo into
    ``data/_partial_batches/<uuid>/demo_<i>``, one ``syncfs``, rename each to ``data/demo_<i>``, then commit
    by advancing ``next_demo_id`` (and ``total`` / ``num_demos``) in ``data/zarr.json``. Readers list only
    ``demo_<i>`` with ``i < next_demo_id``: a batch is visible entirely or not at all, also after SIGKILL.

    On any error the batch is taken out again (the dataset stays as it was). zarr does not cancel the
    sibling writes of a failed one: they can only land in the batch's unique staging folder. The cost per
    demo does not depend on how many the dataset holds (no scan of ``data/``)."""
    with _locked(path) as data:
        next_id, total, count = _counters(data, path)
        _clean_tail(path, next_id)
        ids = list(range(next_id, next_id + len(items)))
        stage = path / "data" / STAGING / uuid.uuid4().hex
        before = {NEXT_ID: next_id, "total": total, "num_demos": count}
        attempted = False
        try:
            data.require_group(STAGING)
            write_group(stage, {})
            jobs = [(stage / demo_name(i), {**attrs, "num_samples": int(num_samples)}, tree)
                    for i, (tree, attrs, num_samples) in zip(ids, items)]
            _parallel(path, jobs)
            if fsync:
                sync_tree(stage)
            for i in ids:
                os.rename(stage / demo_name(i), path / "data" / demo_name(i))
            if fsync:
                fsync_path(path / "data")
            attempted = True
            _commit(data, {NEXT_ID: next_id + len(ids), "total": total + sum(int(n) for _, _, n in items),
                           "num_demos": count + len(ids)})
            if fsync:
                fsync_path(path / "data" / "zarr.json")
                fsync_path(path / "data")
        except BaseException:
            _drain(path, stage)
            _undo_append(data, path, ids, before if attempted else None)
            raise
        shutil.rmtree(path / "data" / STAGING, ignore_errors=True)
    return ids


def _undo_append(data: zarr.Group, path: Path, ids: list[int], counters: dict[str, int] | None) -> None:
    try:
        if counters is not None:
            data.attrs.update(counters)
        for d in [path / "data" / demo_name(i) for i in ids] + [path / "data" / STAGING]:
            if d.exists():
                _remove(d)
    except OSError:
        pass  # what is left is uncommitted: the next append removes it


def set_root_attrs(path: Path, attrs: dict[str, Any], fsync: bool = True) -> None:
    """Update ``data`` attrs under the lock (zarr replaces ``zarr.json`` atomically)."""
    with _locked(path) as data:
        data.attrs.update(attrs)
        if fsync:
            fsync_path(path / "data" / "zarr.json")


def info(path: Path) -> dict[str, Any]:
    root = read_root(path)
    committed, _ = _scan(path, root.get(NEXT_ID))
    return {"root": root, "demos": {i: {"num_samples": int(a["num_samples"]), "success": bool(a.get("success", False))}
                                    for i, a in committed.items()}}


def read(path: Path, demo_id: int) -> tuple[dict[str, Any], dict[str, Any]]:
    return next(read_many(path, [demo_id], None, attrs=True))


def read_many(path: Path, demo_ids: list[int], keys: tuple[str, ...] | None, attrs: bool = False) -> Iterator[Any]:
    """Each demo's tree (with ``attrs``: and its attrs), opening the store once; ``keys`` ("actions",
    "obs/front_head_rgb") limits what is read (all when None). A demo not committed raises ``KeyError``."""
    data = _data(_root(path), path)
    limit = data.attrs.get(NEXT_ID)
    for i in demo_ids:
        stored = _node_attrs(path / "data" / demo_name(i))
        if stored is None or "num_samples" not in stored or (limit is not None and i >= int(limit)):
            raise KeyError(i)
        try:
            tree = read_tree(path / "data" / demo_name(i), keys,
                             fallback=lambda rel, i=i: np.asarray(data[f"{demo_name(i)}/{rel}"][...]))
            yield (tree, {k: from_stored(v) for k, v in stored.items()}) if attrs else tree
        except Exception as e:  # noqa: BLE001
            raise damaged(path, f"{demo_name(i)}: {type(e).__name__}: {e}") from None


def delete(path: Path, ids: list[int], fsync: bool = True) -> None:
    """Delete demos under the lock (atomic rename out of the tree, then rmtree), refresh totals and drop
    them from the filter keys."""
    with _locked(path) as data:
        next_id = _counters(data, path)[0]  # before deleting: ids are never reused
        for i in ids:
            _remove(path / "data" / demo_name(i))
        committed, _ = _scan(path, next_id)
        data.attrs.update({**_totals(committed), NEXT_ID: next_id})
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
    group, mdir = _root(path, writable=True).require_group("mask"), path / "mask"
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
