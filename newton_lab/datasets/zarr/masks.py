"""robomimic filter keys of a zarr dataset: ``mask/<key>``, vlen-utf8 string arrays of demo names."""

from __future__ import annotations

import os
import shutil
import uuid
from pathlib import Path

import numpy as np

from ..files.durability import fsync_path
from ..files.errors import damaged
from ..files.layout import PARTIAL_PREFIX
from .session import fsync_tree, locked, node_attrs, open_root, remove_node


def read_masks(path: Path) -> dict[str, list[str]]:
    """robomimic filter keys: ``mask/<key>`` (vlen-utf8 string arrays) -> demo names."""
    root = open_root(path)
    if not (path / "mask").is_dir():
        return {}
    out = {}
    for entry in sorted(os.scandir(path / "mask"), key=lambda e: e.name):
        if entry.is_dir() and not entry.name.startswith(PARTIAL_PREFIX) and node_attrs(Path(entry.path)) is not None:
            try:
                out[entry.name] = [str(n) for n in np.asarray(root[f"mask/{entry.name}"][...]).reshape(-1)]
            except Exception as e:  # noqa: BLE001
                raise damaged(path, f"mask/{entry.name}: {type(e).__name__}: {e}") from None
    return out


def write_masks(path: Path, masks: dict[str, list[str]], fsync: bool) -> None:
    """Each key is written under a temporary name, then renamed over the old one (under the writer lock)."""
    if not masks:
        return
    group, mdir = open_root(path, writable=True).require_group("mask"), path / "mask"
    for entry in mdir.iterdir():
        if entry.name.startswith(PARTIAL_PREFIX):  # leftovers of a killed session
            shutil.rmtree(entry, ignore_errors=True)
    for key, names in masks.items():
        tmp = f"{PARTIAL_PREFIX}{key}_{uuid.uuid4().hex}"
        group.create_array(tmp, data=np.array(names, dtype=np.dtypes.StringDType()))
        if fsync:
            fsync_tree(mdir / tmp)
        if (mdir / key).exists():
            remove_node(mdir / key)
        os.rename(mdir / tmp, mdir / key)
    if fsync:
        fsync_path(mdir)


def set_masks(path: Path, masks: dict[str, list[str]], fsync: bool = True) -> None:
    """Write (or replace) the filter keys ``mask/<key>`` under the writer lock; other keys are kept."""
    with locked(path):
        write_masks(path, masks, fsync)
