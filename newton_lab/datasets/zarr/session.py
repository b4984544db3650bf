"""Opening a zarr dataset: its root and ``data`` groups, the writer lock (``locked``), node attrs read from
``zarr.json``, a node taken out of the tree (``remove_node``), and the zarr-python store whose writes pass the
fault-injection seam (``FaultStore``, ``drain``)."""

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

import zarr
from zarr.storage import LocalStore

from ..files.durability import fsync_path
from ..files.errors import damaged
from ..files.layout import PARTIAL_PREFIX
from ..files.locking import lock_exclusive
from ..files.write_faults import write_fault_point

_io = threading.Condition()
_in_flight: dict[str, int] = {}  # store root -> writes under way
_refused: set[str] = set()  # "<root>/<prefix>": nodes of failed appends that take no more writes


class FaultStore(LocalStore):
    """LocalStore whose writes pass the fault-injection seam and can be drained after a failure.

    zarr does not cancel the sibling writes of a failed one; :func:`drain` refuses further writes
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


def drain(path: Path, node: Path, timeout: float = 30.0) -> None:
    """Refuse further writes under ``node`` and wait for the writes to ``path`` under way."""
    root = str(path)
    with _io:
        _refused.add(f"{root}/{node.relative_to(path).as_posix()}/")
        _io.wait_for(lambda: not _in_flight.get(root), timeout=timeout)


def open_root(path: Path, writable: bool = False) -> zarr.Group:
    """The dataset's root group (one-line ``damaged`` error when it is not a zarr v3 directory)."""
    if not path.is_dir():
        raise damaged(path, "not a zarr directory")
    try:
        store = FaultStore(path, read_only=not writable)
        return zarr.open_group(store=store, mode="r+" if writable else "r", zarr_format=3, use_consolidated=False)
    except Exception as e:  # noqa: BLE001 - any failure means "not a readable zarr v3 group"
        raise damaged(path, f"not a zarr v3 group: {type(e).__name__}: {e}") from None


def data_group(root: zarr.Group, path: Path) -> zarr.Group:
    """The root's ``data`` group (one-line ``damaged`` error when it has none)."""
    try:
        g = root["data"]
    except Exception:  # noqa: BLE001
        g = None
    if not isinstance(g, zarr.Group):
        raise damaged(path, "no 'data' group")
    return g


def node_attrs(node_dir: Path) -> dict[str, Any] | None:
    """Attributes from a node's zarr.json, or None if missing/unreadable (uncommitted)."""
    try:
        meta = json.loads((node_dir / "zarr.json").read_bytes())
        return dict(meta.get("attributes") or {})
    except (OSError, ValueError, AttributeError):
        return None


def fsync_tree(top: Path) -> None:
    """fsync every file and folder under ``top``."""
    for dirpath, _, files in os.walk(top):
        for name in files:
            fsync_path(Path(dirpath, name))
        fsync_path(Path(dirpath))


@contextmanager
def locked(path: Path) -> Iterator[zarr.Group]:
    """Writer session: the store's ``data`` group, opened under the writer lock."""
    open_root(path)  # same checks/errors as readers before touching anything
    try:
        fd = os.open(path / "zarr.json", os.O_RDWR)  # never written: opened for writing to lock it
    except OSError as e:
        if e.errno in (errno.EACCES, errno.EPERM, errno.EROFS):  # readable, so not damaged: read-only here
            raise ValueError(
                f"{path} is read-only here ({e.strerror}); it was left untouched: make it writable, or "
                "write into another path"
            ) from None
        raise damaged(path, f"zarr.json: {e.strerror}") from None
    try:
        lock_exclusive(fd, path)
        yield data_group(open_root(path, writable=True), path)
    finally:
        os.close(fd)  # releases the lock


def remove_node(entry: Path) -> None:
    """Take a node out of the tree (atomic rename), then delete it."""
    trash = entry.with_name(f"{PARTIAL_PREFIX}deleted_{entry.name}_{uuid.uuid4().hex}")
    os.rename(entry, trash)
    shutil.rmtree(trash, ignore_errors=True)
