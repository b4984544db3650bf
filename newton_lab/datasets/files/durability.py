"""Making written files durable: fsync of one path, or of every file under a folder (``syncfs`` on Linux)."""

from __future__ import annotations

import ctypes
import os
from pathlib import Path


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


_syncfs = getattr(ctypes.CDLL(None, use_errno=True), "syncfs", None)


def sync_tree(top: Path) -> None:
    """Make every file written under ``top`` durable: one ``syncfs`` of its filesystem (Linux), else an
    fsync of each file and directory. A refused flush raises ``OSError`` (EIO, ENOSPC, ...)."""
    if _syncfs is not None:
        fd = os.open(top, os.O_RDONLY)
        try:
            if _syncfs(fd) != 0:
                err = ctypes.get_errno()
                raise OSError(err, os.strerror(err))
        finally:
            os.close(fd)
        return
    for dirpath, _, files in os.walk(top):
        for name in files:
            fsync_path(Path(dirpath, name))
        fsync_path(Path(dirpath))
