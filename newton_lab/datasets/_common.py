"""Helpers shared by the HDF5 and zarr episode stores."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

FORMAT_VERSION = 1
DEMO_RE = re.compile(r"^demo_(\d+)$")
PARTIAL_PREFIX = "_partial_"
RESERVED_DEMO_ATTRS = ("num_samples", "success")
CHUNK_BYTES = 1 << 20  # target bytes per time chunk


def demo_name(demo_id: int) -> str:
    return f"demo_{int(demo_id)}"


def demo_id_of(name: str) -> int | None:
    """Demo id encoded in a group name, or None for anything else."""
    m = DEMO_RE.match(name)
    return int(m.group(1)) if m else None


def damaged(path: Path, reason: str) -> ValueError:
    """One-line error for a path that does not hold a readable dataset."""
    reason = " ".join(str(reason).split())[:200]
    return ValueError(
        f"{path} is not a newton_lab dataset or is damaged ({reason}); it was left untouched: "
        "re-collect the episodes into a new path (or restore a backup)")


def time_chunks(shape: tuple[int, ...], itemsize: int) -> tuple[int, ...]:
    """Chunk shape that splits along time (axis 0) only, ~CHUNK_BYTES per chunk."""
    row = max(1, itemsize * int(np.prod(shape[1:], dtype=np.int64)))
    t = max(1, min(shape[0], CHUNK_BYTES // row))
    return (t, *(max(1, s) for s in shape[1:]))


def py_scalar(value: Any, key: str) -> bool | int | float | str:
    """Convert an attr value to a plain python scalar (JSON/HDF5 friendly)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"attr {key!r} must be a bool/int/float/str scalar, got {type(value).__name__}")


def from_stored(value: Any) -> Any:
    """Attr value as read from a store → plain python value."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, np.generic):
        return value.item()
    return value


def dumps_env_args(env_args: dict) -> str:
    def default(o: Any) -> Any:
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(f"env_args value of type {type(o).__name__} is not JSON serialisable")
    return json.dumps(env_args, default=default, sort_keys=True)


def fsync_path(path: Path) -> None:
    """fsync a file or directory (best effort on platforms without dir fsync)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
