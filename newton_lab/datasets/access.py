"""Dataset access by format: the suffix picks the backend (``hdf5.store`` / ``zarr.store``), the root attrs are
checked, demo ids are parsed and a write the disk refuses becomes one line; and every operation on a dataset other
than appending episodes (``storage.EpisodeWriter``): its info, its demo list, reading episodes, deleting demos,
setting root attrs.

The layout these read, the write protocol and the crash safety are described in ``storage``; the readers return the
same trees and attrs for HDF5, zarr and zarr packs. Every error is one line naming the dataset and the fix.
"""

from __future__ import annotations

import errno
import json
import operator
import os
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

from .files.errors import STORAGE_ERRNOS, DatasetWriteError, damaged
from .files.layout import FORMAT_VERSION, demo_id_of, py_scalar
from .hdf5 import store as hdf5_store
from .zarr import store as zarr_store
from .zarr.inodes import out_of_room

SUFFIXES = {".hdf5": "hdf5", ".h5": "hdf5", ".zarr": "zarr"}
BACKENDS: dict[str, ModuleType] = {"hdf5": hdf5_store, "zarr": zarr_store}
"""Storage module of each format."""

__all__ = [
    "read_dataset_info",
    "read_episode",
    "read_episodes",
    "list_demos",
    "delete_demos",
    "set_dataset_attrs",
    "SUFFIXES",
    "BACKENDS",
]


# ----------------------------------------------------------------------------- dispatch / checks
def _backend(path: str | Path) -> tuple[Path, ModuleType, str]:
    p = Path(path).expanduser()
    fmt = SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        raise ValueError(f"unknown dataset suffix {p.suffix or '(none)'!r} for {p}: use one of {', '.join(SUFFIXES)}")
    return p, BACKENDS[fmt], fmt


def _existing(path: str | Path) -> tuple[Path, ModuleType, str]:
    p, backend, fmt = _backend(path)
    if not p.exists():
        raise FileNotFoundError(f"dataset {p} does not exist; check the path")
    if fmt == "hdf5" and p.is_dir():
        raise damaged(p, "it is a folder, and an HDF5 dataset is one file; a zarr dataset is named .zarr")
    return p, backend, fmt


def _root_meta(p: Path, root: dict[str, Any]) -> dict[str, Any]:
    """Validate ``data`` attrs; returns them with env_args decoded and task_id resolved."""
    try:
        env_args = json.loads(root.get("env_args", "{}"))
        assert isinstance(env_args, dict)
    except (TypeError, ValueError, AssertionError):
        raise damaged(p, "data.attrs['env_args'] is not a JSON object") from None
    task_id = root.get("task_id") or env_args.get("env_name")
    if not isinstance(task_id, str) or not task_id:
        raise damaged(p, "data has no task_id")
    try:
        version = int(root.get("format_version", FORMAT_VERSION))
    except (TypeError, ValueError):
        raise damaged(p, "data.attrs['format_version'] is not an int") from None
    if version > FORMAT_VERSION:
        raise ValueError(
            f"{p} has format_version {version}, newer than this newton_lab "
            f"({FORMAT_VERSION}); upgrade newton_lab to read it"
        )
    return {**root, "env_args": env_args, "task_id": task_id, "format_version": version}


def _describe_ids(ids: list[int]) -> str:
    if not ids:
        return "none (the dataset is empty)"
    runs, start = [], ids[0]
    for a, b in zip(ids, ids[1:] + [None]):
        if b != a + 1:
            runs.append(f"{start}..{a}" if a != start else f"{a}")
            start = b
    return ", ".join(runs[:8]) + (", ..." if len(runs) > 8 else "")


def _as_id(demo_id: int | str) -> int:
    if isinstance(demo_id, str):
        parsed = demo_id_of(demo_id) if not demo_id.isdigit() else int(demo_id)
        if parsed is None:
            raise KeyError(f"bad demo id {demo_id!r}: use an int or 'demo_<i>'")
        return parsed
    return operator.index(demo_id)


def _episodes(n: int, kind: str = "") -> str:
    return f"{n} {kind}episode" if n == 1 else f"{n} {kind}episodes"


def _medium_errno(exc: OSError) -> int | None:
    """errno of an error of the storage medium (disk full, I/O error, ...), else None."""
    if exc.errno in STORAGE_ERRNOS:
        return exc.errno
    text = str(exc).lower()  # h5py reports some OS errors in words only
    return next((e for e in STORAGE_ERRNOS if os.strerror(e).lower() in text), None)


@contextmanager
def _medium_errors(p: Path, backend: ModuleType, done: str) -> Iterator[None]:
    """Turn a write the disk refused into one line, :class:`DatasetWriteError` (others pass unchanged)."""
    try:
        yield
    except OSError as exc:
        err = _medium_errno(exc)
        if err is None or isinstance(exc, DatasetWriteError):
            raise
        try:
            holds = f"{p} holds {_episodes(len(backend.info(p)['demos']), 'finished ')}"
        except FileNotFoundError:
            holds = f"nothing was written to {p}"
        except (OSError, ValueError):
            holds = f"{p} could not be read back"
        words, hint = os.strerror(err).lower(), ""
        if err == errno.EDQUOT:
            words = "disk full"
        elif err == errno.ENOSPC:
            words, hint = out_of_room(p)
        raise DatasetWriteError(f"{words} {done}; {holds}{hint}", err) from None


def _missing_id(p: Path, demo_id: Any, ids: list[int]) -> KeyError:
    return KeyError(f"demo {demo_id} not in {p}; available ids: {_describe_ids(ids)}")


# ----------------------------------------------------------------------------- readers
def read_dataset_info(path: str | Path) -> dict[str, Any]:
    """Task, env_args, totals and per-demo ``num_samples``/``success`` (committed demos only)."""
    p, backend, fmt = _existing(path)
    raw = backend.info(p)
    meta = _root_meta(p, raw["root"])
    demos = dict(sorted(raw["demos"].items()))
    return {
        "path": str(p),
        "format": fmt,
        "format_version": meta["format_version"],
        "task_id": meta["task_id"],
        "env_args": meta["env_args"],
        "num_demos": len(demos),
        "total": sum(d["num_samples"] for d in demos.values()),
        "demo_ids": list(demos),
        "demos": demos,
        "provenance": json.loads(raw["root"].get("provenance", "[]")),
    }


def set_dataset_attrs(path: str | Path, attrs: Mapping[str, Any]) -> None:
    """Update scalar / string attrs of the ``data`` group (e.g. ``provenance`` JSON); crash safe."""
    p, backend, _ = _existing(path)
    with _medium_errors(p, backend, "while setting dataset attrs"):
        backend.set_root_attrs(p, {k: py_scalar(v, k) for k, v in attrs.items()})


def list_demos(path: str | Path) -> list[int]:
    """Sorted ids of the committed demos."""
    p, backend, _ = _existing(path)
    return sorted(backend.info(p)["demos"])


def read_episode(path: str | Path, demo_id: int | str) -> dict[str, Any]:
    """Nested dict of numpy arrays for one demo, plus its attrs under ``"attrs"``."""
    p, backend, _ = _existing(path)
    i = _as_id(demo_id)
    try:
        tree, attrs = backend.read(p, i)
    except KeyError:
        raise _missing_id(p, demo_id, sorted(backend.info(p)["demos"])) from None
    return {**tree, "attrs": attrs}


def read_episodes(
    path: str | Path, demo_ids: Iterable[int | str], keys: Iterable[str] | None = None, *, attrs: bool = False
) -> Iterator[dict[str, Any]]:
    """``read_episode`` of each of ``demo_ids`` in turn, through one open dataset (one walk of its demo list, not
    one per episode), with ``"attrs"`` only when ``attrs``; ``keys`` ("actions", "obs/front_head_rgb", ...) limits
    what is read to those arrays (a key a demo lacks is left out; all arrays when None)."""
    p, backend, _ = _existing(path)
    ids = [_as_id(i) for i in demo_ids]
    try:
        if attrs:
            yield from ({**tree, "attrs": a} for tree, a in backend.read_many(p, ids, None, attrs=True))
            return
        yield from backend.read_many(p, ids, None if keys is None else tuple(keys))
    except KeyError as e:
        raise _missing_id(p, e.args[0], sorted(backend.info(p)["demos"])) from None


def delete_demos(path: str | Path, ids: Iterable[int | str]) -> list[int]:
    """Remove demos (all ids checked first) and refresh num_demos/total; returns the remaining ids."""
    p, backend, _ = _existing(path)
    wanted = sorted({_as_id(i) for i in ids})
    present = sorted(backend.info(p)["demos"])
    for i in wanted:
        if i not in present:
            raise _missing_id(p, i, present)
    if wanted:
        with _medium_errors(p, backend, "while deleting demos"):
            backend.delete(p, wanted)
    return [i for i in present if i not in wanted]
