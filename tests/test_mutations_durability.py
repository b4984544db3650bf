"""Durability order of both writers, checked through their I/O the way SQLite's crash tests use a VFS: every write,
sync, rename and unlink of one append is logged, and a power cut at any point must find the commit marker only
after the data it commits is on disk (the journal before the bytes it saves are overwritten, the commit synced
before the append returns). No physics."""

from __future__ import annotations

import os
import pathlib
from collections.abc import Callable

import numpy as np
import pytest

from newton_lab.datasets import list_demos, open_writer, read_episode
from newton_lab.datasets.files import durability
from newton_lab.datasets.hdf5 import journal as _journal
from newton_lab.datasets.zarr import nodes as zarr_nodes, session as zarr_session, store as zarr_store

STEPS = 30


def episode(seed: int) -> dict:
    rng = np.random.default_rng(seed)
    return {
        "actions": rng.standard_normal((STEPS, 7)).astype(np.float32),
        "obs": {
            "eef_pos": rng.standard_normal((STEPS, 3)),
            "rgb": rng.integers(0, 255, (STEPS, 8, 8, 3), dtype=np.uint8),
        },
    }


def _fd_path(fd: int) -> str:
    return os.readlink(f"/proc/self/fd/{fd}")


class Disk:
    """What a power cut keeps: a file's content once an fsync (or a syncfs) followed its last write, a folder's
    entries (renames, unlinks) once the folder is fsynced. ``events`` logs each operation in order."""

    def __init__(self) -> None:
        self.events: list[tuple[str, str]] = []
        self.watch: Callable[[str, str], None] | None = None
        """Called with each event before it takes effect: sees what a power cut at that moment would find."""
        self.dirty_files: set[str] = set()
        self.dirty_dirs: set[str] = set()
        self.size0: dict[str, int] = {}
        """Size of a file when its session began [bytes]: a write below it overwrites committed bytes."""

    def forget(self) -> None:
        """Start a new log, everything so far on disk."""
        self.events.clear()
        self.dirty_files.clear()
        self.dirty_dirs.clear()

    def log(self, kind: str, path: str) -> None:
        if self.watch is not None:
            self.watch(kind, path)
        self.events.append((kind, path))

    def write(self, path: str) -> None:
        self.log("write", path)
        self.dirty_files.add(path)

    def entry(self, kind: str, path: str) -> None:
        self.log(kind, path)
        self.dirty_dirs.add(os.path.dirname(path))

    def fsync(self, path: str) -> None:
        self.log("fsync", path)
        self.dirty_files.discard(path)
        self.dirty_dirs.discard(path)

    def syncfs(self) -> None:
        self.log("syncfs", "")
        self.dirty_files.clear()
        self.dirty_dirs.clear()

    def lost(self, under: str = "") -> list[str]:
        """Files and folders under ``under`` whose last change a power cut now would lose."""
        return sorted(p for p in self.dirty_files | self.dirty_dirs if p.startswith(under))


@pytest.fixture
def disk(monkeypatch) -> Disk:
    """Log the writers' file I/O in this process (zarr batches on threads, not writer processes)."""
    d = Disk()
    real_fsync, real_unlink, real_rename, real_replace = os.fsync, pathlib.Path.unlink, os.rename, os.replace

    def fsync(fd):
        d.fsync(_fd_path(fd))
        return real_fsync(fd)

    def unlink(self, missing_ok=False):
        d.entry("unlink", str(self.absolute()))
        return real_unlink(self, missing_ok=missing_ok)

    def rename(src, dst, *args, **kwargs):
        d.entry("rename", os.path.abspath(dst))
        return real_rename(src, dst, *args, **kwargs)

    def replace(src, dst, *args, **kwargs):
        d.entry("rename", os.path.abspath(dst))
        return real_replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "rename", rename)
    monkeypatch.setattr(os, "replace", replace)
    monkeypatch.setattr(pathlib.Path, "unlink", unlink)
    real_syncfs = durability._syncfs
    if real_syncfs is not None:
        monkeypatch.setattr(durability, "_syncfs", lambda fd: (d.syncfs(), real_syncfs(fd))[1])
    # HDF5: every byte goes through the journaled file's _write_all (data file and journal alike)
    real_write_all = _journal._write_all

    def write_all(f, data):
        path = _fd_path(f.fileno())
        if not path.endswith("-journal") and f.tell() < d.size0.get(path, 0):
            d.log("overwrite", path)
        d.write(path)
        return real_write_all(f, data)

    monkeypatch.setattr(_journal, "_write_all", write_all)
    # zarr: demo files through zarr_nodes.write_file, metadata (and the commit) through the store's _set
    real_write_file = zarr_nodes.write_file
    monkeypatch.setattr(
        zarr_nodes, "write_file", lambda path, data: (d.write(os.path.abspath(path)), real_write_file(path, data))[1]
    )
    real_set = zarr_session.FaultStore._set

    async def store_set(self, key, value, exclusive=False):
        await real_set(self, key, value, exclusive=exclusive)
        d.write(os.path.abspath(os.path.join(str(self.root), key)))

    monkeypatch.setattr(zarr_session.FaultStore, "_set", store_set)
    return d


def test_hdf5_append_syncs_data_before_its_commit_and_the_journal_before_overwriting(tmp_path, disk):
    path = tmp_path / "ds.hdf5"
    with open_writer(path, task_id="pick_cube", env_args={}) as w:
        w.append_episodes([(episode(s), True, {"seed": s}) for s in range(2)])
        disk.size0[str(path)] = path.stat().st_size
        disk.forget()
        journal = str(_journal.journal_path(path))
        seen = {"overwrites": 0, "commit": False}

        def check(kind: str, where: str) -> None:
            if kind == "overwrite":  # bytes that existed before the session: the journal must hold them, durably
                seen["overwrites"] += 1
                assert journal not in disk.lost(), "a committed byte overwritten before its journal copy synced"
            if kind == "unlink" and where == journal and not seen["commit"]:  # the commit point
                seen["commit"] = True
                assert str(path) not in disk.lost(), "journal removed (commit) before the data was fsynced"

        disk.watch = check
        assert w.append_episodes([(episode(s), True, {"seed": s}) for s in (2, 3)]) == [2, 3]
    assert seen["commit"] and seen["overwrites"] > 0, "the journaled file no longer goes through _write_all"
    assert disk.lost(str(tmp_path)) == [], "the append returned with its commit not yet durable"
    assert list_demos(path) == [0, 1, 2, 3]


def test_zarr_append_syncs_the_batch_before_its_commit_and_the_commit_before_returning(tmp_path, disk):
    path = tmp_path / "ds.zarr"
    with open_writer(path, task_id="pick_cube", env_args={}) as w:
        w.append_episodes([(episode(s), True, {"seed": s}) for s in range(2)])
        disk.forget()
        marker = str(path / "data" / "zarr.json")
        seen = {"demo_files": set(), "renamed": set(), "commit": False}

        def check(kind: str, where: str) -> None:
            if kind == "write" and zarr_store.STAGING in where:
                seen["demo_files"].add(where)
            if kind == "rename":
                seen["renamed"].add(os.path.basename(where))
            # the commit: zarr replaces data/zarr.json, whose next_demo_id then counts the batch
            if kind in ("write", "rename") and where == marker and not seen["commit"]:
                seen["commit"] = True
                assert disk.lost(str(path / "data")) == [], "the batch's demos were not durable at its commit"
                assert {"demo_2", "demo_3"} <= seen["renamed"], "committed before the demos were renamed into data/"

        disk.watch = check
        assert w.append_episodes([(episode(s), True, {"seed": s}) for s in (2, 3)]) == [2, 3]
    assert seen["commit"] and len(seen["demo_files"]) > 10, "the zarr writer no longer goes through the logged calls"
    assert disk.lost(str(path)) == [], "the append returned with its commit not yet durable"
    for s in range(4):
        np.testing.assert_array_equal(read_episode(path, s)["actions"], episode(s)["actions"])
