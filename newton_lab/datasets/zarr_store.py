"""zarr v3 backend (directory store); a demo is committed by its ``num_samples`` attr."""

from __future__ import annotations

import json
import os
import shutil
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import zarr
from zarr.storage import LocalStore

from ._common import PARTIAL_PREFIX, damaged, demo_id_of, demo_name, from_stored, fsync_path, time_chunks


def _root(path: Path, writable: bool = False) -> zarr.Group:
    if not path.is_dir():
        raise damaged(path, "not a zarr directory")
    try:
        store = LocalStore(path, read_only=not writable)
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
        os.rename(tmp, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if fsync:
        fsync_path(path.parent)


def read_root(path: Path) -> dict[str, Any]:
    return {k: from_stored(v) for k, v in _data(_root(path), path).attrs.asdict().items()}


def append(path: Path, tree: dict[str, Any], attrs: dict[str, Any], num_samples: int, fsync: bool) -> int:
    """Write arrays + attrs, then ``num_samples`` last (commit), then refresh ``data`` totals."""
    data = _data(_root(path, writable=True), path)
    committed, leftovers = _scan(path)
    for leftover in leftovers:
        if leftover.is_dir():
            shutil.rmtree(leftover, ignore_errors=True)
        else:
            leftover.unlink(missing_ok=True)
    demo_id = max(committed, default=-1) + 1
    g = data.create_group(demo_name(demo_id), attributes=attrs)
    _write_tree(g, tree)
    demo_dir = path / "data" / demo_name(demo_id)
    if fsync:
        _fsync_tree(demo_dir)
    g.attrs["num_samples"] = int(num_samples)  # commit marker (atomic zarr.json replace)
    if fsync:
        fsync_path(demo_dir / "zarr.json")
        fsync_path(demo_dir)
    committed[demo_id] = {"num_samples": int(num_samples)}
    data.attrs.update(_totals(committed))
    if fsync:
        fsync_path(path / "data" / "zarr.json")
        fsync_path(path / "data")
    return demo_id


def set_root_attrs(path: Path, attrs: dict[str, Any], fsync: bool = True) -> None:
    """Update ``data`` attrs (zarr replaces ``zarr.json`` atomically)."""
    _data(_root(path, writable=True), path).attrs.update(attrs)
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
    """Delete demos (atomic rename out of the tree, then rmtree) and refresh totals."""
    data = _data(_root(path, writable=True), path)
    for i in ids:
        src = path / "data" / demo_name(i)
        trash = src.with_name(f"{PARTIAL_PREFIX}deleted_{demo_name(i)}_{uuid.uuid4().hex}")
        os.rename(src, trash)
        shutil.rmtree(trash, ignore_errors=True)
    committed, _ = _scan(path)
    data.attrs.update(_totals(committed))
    if fsync:
        fsync_path(path / "data")
