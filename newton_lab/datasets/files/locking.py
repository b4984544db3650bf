"""The writer lock of both formats: an exclusive ``flock`` taken through a fairness turnstile, with a bounded wait
and a one-line error naming the holder."""

from __future__ import annotations

import errno
import fcntl
import os
import time
from pathlib import Path

from .errors import DatasetLockedError

LOCK_WAIT_S = 10.0
"""Bounded wait for the writer lock [s] (both formats)."""
TURNSTILE = 1 << 62
"""Byte offset of the writers' fairness lock."""


def lock_holder(st: os.stat_result) -> int | None:
    """Pid holding the writer ``flock`` on the file of ``st`` (from ``/proc/locks``; None where unknown)."""
    key = (os.major(st.st_dev), os.minor(st.st_dev), st.st_ino)
    try:
        lines = Path("/proc/locks").read_text().splitlines()
    except OSError:
        return None
    found = []
    for fields in (line.split() for line in lines):
        if len(fields) < 6 or "->" in fields:
            continue  # a waiter, not a holder
        try:
            major, minor, ino = fields[5].split(":")
            if (int(major, 16), int(minor, 16), int(ino)) == key and int(fields[4]) > 0:
                found.append((fields[1] != "FLOCK", int(fields[4])))
        except ValueError:
            continue
    return min(found)[1] if found else None


def locked_error(path: Path, st: os.stat_result) -> DatasetLockedError:
    pid = lock_holder(st)
    who = f"process {pid}" if pid is not None else "another process"
    return DatasetLockedError(f"{path} is locked by {who}; wait for it or write to another path")


def _poll(take, fd: int, path: Path, deadline: float) -> None:
    delay = 0.001
    while True:
        try:
            take()
            return
        except OSError as e:
            if e.errno not in (errno.EAGAIN, errno.EACCES):
                raise
            if time.monotonic() > deadline:
                raise locked_error(path, os.fstat(fd)) from None
            time.sleep(delay)
            delay = min(2 * delay, 0.05)


def lock_exclusive(fd: int, path: Path, wait_s: float | None = None) -> None:
    """The writer lock of both formats: exclusive ``flock`` on ``fd`` (opened for writing), waiting at
    most ``wait_s`` (default ``LOCK_WAIT_S``), then a one-line :class:`DatasetLockedError` naming the holder.

    Waiters first take a turnstile (a POSIX record lock on one byte past any real data, independent of
    ``flock``), so a writer that appends in a tight loop cannot starve another: on its next append it
    queues behind the waiter. Both are released when ``fd`` is closed or the process dies.
    """
    deadline = time.monotonic() + (LOCK_WAIT_S if wait_s is None else wait_s)
    _poll(lambda: fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, TURNSTILE), fd, path, deadline)
    try:
        _poll(lambda: fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB), fd, path, deadline)
    finally:
        fcntl.lockf(fd, fcntl.LOCK_UN, 1, TURNSTILE)
