"""zarr v3 backend (directory store): a batch of demos is written under a staging folder, renamed to
``demo_<i>`` groups (small batches) or ``pack_<first id>`` groups (batches of ``ZarrWriteSettings.pack_min_batch`` demos
or more, see ``zarr.packs``) and committed by advancing the ``data`` attr ``next_demo_id``; a ``demo_<i>`` without
``num_samples``, or a ``demo_<i>`` / ``pack_<i>`` with ``i >= next_demo_id``, is a leftover (readers skip it, the
next append removes it).

Writers (append, delete, root attrs) hold the writer lock of both formats (``files.locking.lock_exclusive``)
on the store's root ``zarr.json``, a file written once at creation and never replaced, so they are
serialised and demo ids come from ``next_demo_id``. Readers take no lock.
"""

from __future__ import annotations

import errno
import os
import shutil
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import zarr
from zarr.storage import LocalStore

from ..files.durability import fsync_path, sync_tree
from ..files.errors import damaged
from ..files.layout import NEXT_ID, PARTIAL_PREFIX, StoredDemo, demo_id_of, demo_name, from_stored
from . import batch_writes, packs as zarr_packs
from .masks import read_masks, set_masks, write_masks
from .nodes import read_tree, write_group
from .packs import PackJob, PackReader, batch_jobs, pack_first_of, pack_name
from .session import data_group, drain, fsync_tree, locked, node_attrs, open_root, remove_node
from .settings import ZarrWriteSettings

BATCH_SECONDS = {"files": 0.0, "sync": 0.0}
"""Seconds this process's zarr batch appends spent encoding and writing their demos' files (writer processes or
threads) and in the one ``syncfs`` that makes them durable; cumulative, read as differences (``bench-collect``'s
writer split)."""

__all__ = [
    "create",
    "read_root",
    "append",
    "set_root_attrs",
    "info",
    "read",
    "read_many",
    "delete",
    "read_masks",
    "set_masks",
]

STAGING = f"{PARTIAL_PREFIX}batches"  # data/_partial_batches/<uuid>/{demo,pack}_<i>: a batch being written

Item = tuple[Any, dict[str, Any], int]
"""A demo of a batch: (tree or ``StoredDemo``, attrs, num_samples)."""


def _scan(path: Path, limit: int | None = None) -> tuple[dict[int, dict[str, Any]], list[Path]]:
    """(committed demo id -> attrs, leftovers of killed appends/deletes: dirs and ``*.partial`` files), packed
    demos from their packs' indexes. With ``limit`` (the ``next_demo_id`` attr) a ``demo_<i>`` or ``pack_<i>``,
    ``i >= limit``, is a leftover of a killed batch."""
    committed, leftovers = {}, []
    for entry in os.scandir(path / "data"):
        if not entry.is_dir():
            if entry.name.endswith(".partial"):  # zarr's temp file of an interrupted metadata write
                leftovers.append(Path(entry.path))
            continue
        first = pack_first_of(entry.name)
        if first is not None:
            index = zarr_packs.read_index(entry.path)
            if index is not None and (limit is None or first < int(limit)):
                committed.update({int(i): attrs for i, (_, _, attrs) in index["demos"].items()})
            else:
                leftovers.append(Path(entry.path))
            continue
        i = demo_id_of(entry.name)
        attrs = node_attrs(Path(entry.path)) if i is not None else None
        if attrs is not None and "num_samples" in attrs and (limit is None or i < int(limit)):
            committed[i] = attrs
        elif i is not None or entry.name.startswith(PARTIAL_PREFIX):
            leftovers.append(Path(entry.path))
    return committed, leftovers


def _totals(committed: dict[int, dict[str, Any]]) -> dict[str, int]:
    return {"total": sum(int(a["num_samples"]) for a in committed.values()), "num_demos": len(committed)}


def create(path: Path, root_attrs: dict[str, Any], fsync: bool) -> None:
    """Create an empty dataset atomically (temp directory renamed into place)."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}.partial")
    try:
        root = zarr.open_group(store=LocalStore(tmp), mode="w-", zarr_format=3)
        root.create_group("data", attributes=root_attrs)
        if fsync:
            fsync_tree(tmp)
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
    return {k: from_stored(v) for k, v in data_group(open_root(path), path).attrs.asdict().items()}


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
    """Remove what a killed batch left (under the lock): its staging folder and the ``demo_<i>`` / ``pack_<i>`` it
    had renamed into place, ``i >= next_id`` (never committed: readers ignore them). Looks only at those names
    (a pack's index says where the next one starts), unless a pack cannot be read: then at every name."""
    staging = path / "data" / STAGING
    if staging.exists():
        shutil.rmtree(staging, ignore_errors=True)
    while True:
        demo, pack = path / "data" / demo_name(next_id), path / "data" / pack_name(next_id)
        if demo.exists():
            remove_node(demo)
            next_id += 1
        elif pack.exists():
            index = zarr_packs.read_index(pack)
            remove_node(pack)
            if index is None:
                for entry in os.scandir(path / "data"):
                    i = demo_id_of(entry.name)
                    i = pack_first_of(entry.name) if i is None else i
                    if i is not None and i >= next_id:
                        remove_node(Path(entry.path))
                return
            next_id += len(index["demos"])
        else:
            return


def _commit(data: zarr.Group, counters: dict[str, int]) -> None:
    """The commit point of a batch: ``data/zarr.json`` (replaced atomically) gets the new ``next_demo_id``."""
    data.attrs.update(counters)


def append(
    path: Path, items: list[tuple[dict[str, Any], dict[str, Any], int]], fsync: bool, settings: ZarrWriteSettings
) -> list[int]:
    """Under the lock, write ``items`` ((tree, attrs, num_samples), ...) as one batch: each demo (or each pack of
    demos, ``zarr.packs.batch_jobs``) into ``data/_partial_batches/<uuid>/demo_<i>`` (``pack_<i>``), one
    ``syncfs``, rename each into ``data/``, then commit by advancing ``next_demo_id`` (and ``total`` /
    ``num_demos``) in ``data/zarr.json``. Readers list only ``demo_<i>`` / ``pack_<i>`` with ``i < next_demo_id``:
    a batch is visible entirely or not at all, also after SIGKILL.

    On any error the batch is taken out again (the dataset stays as it was). zarr does not cancel the
    sibling writes of a failed one: they can only land in the batch's unique staging folder. The cost per
    demo does not depend on how many the dataset holds (no scan of ``data/``)."""
    min_batch = settings.pack_min_batch
    return _append_jobs(
        path,
        len(items),
        sum(int(n) for _, _, n in items),
        fsync,
        settings,
        lambda stage, ids: batch_jobs(stage, ids, _unpacked(items, min_batch), min_batch),
    )


def append_joined(
    path: Path,
    arrays: dict[str, np.ndarray],
    layout: dict[str, int | None],
    attrs: list[dict[str, Any]],
    fsync: bool,
    settings: ZarrWriteSettings,
) -> list[int]:
    """As :func:`append`, for demos whose arrays come joined (``columns.DemoBlock.arrays``; ``attrs`` per demo with
    its ``num_samples``): one pack, written straight from them."""
    return _append_jobs(
        path,
        len(attrs),
        sum(int(a["num_samples"]) for a in attrs),
        fsync,
        settings,
        lambda stage, ids: [PackJob(stage / pack_name(ids[0]), ids, attrs, None, layout, arrays)],
    )


def _append_jobs(
    path: Path, demos: int, samples: int, fsync: bool, settings: ZarrWriteSettings, make_jobs
) -> list[int]:
    """The batch write of :func:`append`: ``make_jobs(stage, ids)`` gives the write jobs of the ``demos`` new ids."""
    with locked(path) as data:
        next_id, total, count = _counters(data, path)
        _clean_tail(path, next_id)
        ids = list(range(next_id, next_id + demos))
        stage = path / "data" / STAGING / uuid.uuid4().hex
        before = {NEXT_ID: next_id, "total": total, "num_demos": count}
        attempted, names = False, []
        try:
            data.require_group(STAGING)
            write_group(stage, {})
            jobs = make_jobs(stage, ids)
            names = [(job.node if isinstance(job, PackJob) else job[0]).name for job in jobs]
            t0 = time.perf_counter()
            batch_writes.write_batch(path, jobs, settings)
            t1 = time.perf_counter()
            if fsync:
                sync_tree(stage)
            BATCH_SECONDS["files"] += t1 - t0
            BATCH_SECONDS["sync"] += time.perf_counter() - t1
            for name in names:
                os.rename(stage / name, path / "data" / name)
            if fsync:
                fsync_path(path / "data")
            attempted = True
            _commit(data, {NEXT_ID: next_id + len(ids), "total": total + samples, "num_demos": count + len(ids)})
            if fsync:
                fsync_path(path / "data" / "zarr.json")
                fsync_path(path / "data")
        except BaseException:
            drain(path, stage)
            _undo_append(data, path, names, before if attempted else None)
            raise
        shutil.rmtree(path / "data" / STAGING, ignore_errors=True)
    return ids


def _unpacked(items: list[Item], pack_min_batch: int) -> list[Item]:
    """``items`` with each copy (``StoredDemo``) of a packed demo read back as its tree and its source attrs updated
    with the item's (a pack's files hold many demos: there are none to copy); in a batch large enough to be packed,
    every copy (its demos then land in packs too)."""
    wanted: dict[Path, list[int]] = {}
    every = len(items) >= pack_min_batch
    for k, (tree, _, _) in enumerate(items):
        if isinstance(tree, StoredDemo) and (every or not (tree.path / "data" / demo_name(tree.demo_id)).is_dir()):
            wanted.setdefault(tree.path, []).append(k)
    items = list(items)
    for source, ks in wanted.items():
        for k, (tree, stored) in zip(ks, read_many(source, [items[k][0].demo_id for k in ks], None, attrs=True)):
            stored.pop("num_samples", None)
            items[k] = (tree, {**stored, **items[k][1]}, items[k][2])
    return items


def _undo_append(data: zarr.Group, path: Path, names: list[str], counters: dict[str, int] | None) -> None:
    try:
        if counters is not None:
            data.attrs.update(counters)
        for d in [path / "data" / name for name in names] + [path / "data" / STAGING]:
            if d.exists():
                remove_node(d)
    except OSError:
        pass  # what is left is uncommitted: the next append removes it


def set_root_attrs(path: Path, attrs: dict[str, Any], fsync: bool = True) -> None:
    """Update ``data`` attrs under the lock (zarr replaces ``zarr.json`` atomically)."""
    with locked(path) as data:
        data.attrs.update(attrs)
        if fsync:
            fsync_path(path / "data" / "zarr.json")


def info(path: Path) -> dict[str, Any]:
    root = read_root(path)
    committed, _ = _scan(path, root.get(NEXT_ID))
    return {
        "root": root,
        "demos": {
            i: {"num_samples": int(a["num_samples"]), "success": bool(a.get("success", False))}
            for i, a in committed.items()
        },
    }


def read(path: Path, demo_id: int) -> tuple[dict[str, Any], dict[str, Any]]:
    return next(read_many(path, [demo_id], None, attrs=True))


def read_many(path: Path, demo_ids: list[int], keys: tuple[str, ...] | None, attrs: bool = False) -> Iterator[Any]:
    """Each demo's tree (with ``attrs``: and its attrs), opening the store once; ``keys`` ("actions",
    "obs/front_head_rgb") limits what is read (all when None). A demo not committed raises ``KeyError``."""
    data = data_group(open_root(path), path)
    limit = data.attrs.get(NEXT_ID)
    packs = PackReader(
        path / "data", None if limit is None else int(limit), fallback=lambda rel, a, b: np.asarray(data[rel][a:b])
    )
    for i in demo_ids:
        stored = node_attrs(path / "data" / demo_name(i))
        if stored is None and (found := packs.locate(i)) is not None:
            try:
                tree = packs.read(found, keys)
            except Exception as e:  # noqa: BLE001
                raise damaged(path, f"{found[0]} (demo {i}): {type(e).__name__}: {e}") from None
            yield (tree, {k: from_stored(v) for k, v in found[3].items()}) if attrs else tree
            continue
        if stored is None or "num_samples" not in stored or (limit is not None and i >= int(limit)):
            raise KeyError(i)
        try:
            tree = read_tree(
                path / "data" / demo_name(i),
                keys,
                fallback=lambda rel, i=i: np.asarray(data[f"{demo_name(i)}/{rel}"][...]),
            )
            yield (tree, {k: from_stored(v) for k, v in stored.items()}) if attrs else tree
        except Exception as e:  # noqa: BLE001
            raise damaged(path, f"{demo_name(i)}: {type(e).__name__}: {e}") from None


def delete(path: Path, ids: list[int], fsync: bool = True) -> None:
    """Delete demos under the lock (a ``demo_<i>``: atomic rename out of the tree, then rmtree; a packed demo: out
    of its pack's index), refresh totals and drop them from the filter keys."""
    with locked(path) as data:
        next_id = _counters(data, path)[0]  # before deleting: ids are never reused
        packs, packed = PackReader(path / "data", next_id, fallback=None), {}
        for i in ids:
            if (path / "data" / demo_name(i)).is_dir():
                remove_node(path / "data" / demo_name(i))
            elif (found := packs.locate(i)) is not None:
                packed.setdefault(found[0], []).append(i)
        for name, dropped in packed.items():  # a pack keeps its rows until its last demo goes
            if not zarr_packs.drop(path / "data" / name, dropped, fsync):
                remove_node(path / "data" / name)
        committed, _ = _scan(path, next_id)
        data.attrs.update({**_totals(committed), NEXT_ID: next_id})
        if fsync:
            fsync_path(path / "data")
        gone = {demo_name(i) for i in ids}
        write_masks(path, {k: [n for n in names if n not in gone] for k, names in read_masks(path).items()}, fsync)
