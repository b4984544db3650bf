"""The stored layout both formats share: format version, demo names and ids, the partial-write prefix, time chunks,
and attr values as they go in and come out of a store."""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

FORMAT_VERSION = 2  # 2: flat (T, D) ``states`` / ``initial_state``, ``rewards``, ``dones``, ``mask/``
DEMO_RE = re.compile(r"^demo_(\d+)$")
PARTIAL_PREFIX = "_partial_"
RESERVED_DEMO_ATTRS = ("num_samples", "success")
NEXT_ID = "next_demo_id"  # root attr: the id the next appended demo gets (ids are never reused)
CHUNK_BYTES = 1 << 20  # target bytes per time chunk


def demo_name(demo_id: int) -> str:
    return f"demo_{int(demo_id)}"


@dataclass(frozen=True)
class StoredDemo:
    """A committed demo of another dataset of the same format, appended as stored: its arrays are copied (HDF5:
    ``H5Ocopy``; zarr: the demo's files, unless the source demo or the batch is packed), not decoded and encoded
    again. The copy keeps the source's attrs, updated with the item's."""

    path: Path
    demo_id: int


def nest(flat: dict[str, Any]) -> dict[str, Any]:
    """``{"obs/rgb": a, "actions": b}`` -> ``{"obs": {"rgb": a}, "actions": b}``."""
    tree: dict[str, Any] = {}
    for key, value in flat.items():
        put(tree, key, value)
    return tree


def put(tree: dict[str, Any], key: str, value: Any) -> None:
    """Set ``tree[a][b][c] = value`` for ``key`` "a/b/c" (making the groups on the way)."""
    node = tree
    parts = key.split("/")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = value


def demo_id_of(name: str) -> int | None:
    """Demo id encoded in a group name, or None for anything else."""
    m = DEMO_RE.match(name)
    return int(m.group(1)) if m else None


def time_chunks(shape: tuple[int, ...], itemsize: int) -> tuple[int, ...]:
    """Chunk shape that splits along time (axis 0) only, ~CHUNK_BYTES per chunk."""
    row = max(1, itemsize * math.prod(shape[1:]))
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
