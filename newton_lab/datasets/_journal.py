"""Rollback journal that makes in-place edits of one file atomic (used for HDF5 appends).

HDF5 has no atomic commit: a writer killed while the library flushes its metadata cache can
leave dangling links or overlapping allocations. So every write session goes through
:class:`JournaledFile`: before a byte that existed when the session started is overwritten,
its original content is appended to ``<file>-journal``. Deleting the journal is the commit;
a journal found later (writer killed) is rolled back, restoring the last committed file.
An exclusive ``flock`` on the data file (the lock HDF5 itself uses) serialises sessions.
"""

from __future__ import annotations

import fcntl
import os
import struct
import time
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

MAGIC = b"NLJOURN1"
_HEAD = struct.Struct("<8sQI")  # magic, original size, crc32 of the first two
_REC = struct.Struct("<QQI")  # offset, length, crc32 of the saved bytes


def journal_path(path: Path) -> Path:
    return path.with_name(path.name + "-journal")


def _fsync_dir(path: Path) -> None:
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _lock(fd: int, path: Path, wait_s: float) -> None:
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() > deadline:
                raise BlockingIOError(f"{path} is locked by another process (a writer or reader); "
                                      "retry when it is done") from None
            time.sleep(0.05)


def _rollback(raw, path: Path, fsync: bool) -> None:
    """Undo an interrupted session recorded in the journal (idempotent), then drop the journal."""
    jpath = journal_path(path)
    try:
        blob = jpath.read_bytes()
    except FileNotFoundError:
        return
    if len(blob) >= _HEAD.size:
        magic, size0, crc = _HEAD.unpack_from(blob)
        if magic == MAGIC and crc == zlib.crc32(blob[:_HEAD.size - 4]):
            records, pos = [], _HEAD.size
            while pos + _REC.size <= len(blob):
                off, n, rcrc = _REC.unpack_from(blob, pos)
                data = blob[pos + _REC.size: pos + _REC.size + n]
                if len(data) != n or zlib.crc32(data) != rcrc:
                    break  # torn tail: its in-place write never happened
                records.append((off, data))
                pos += _REC.size + n
            for off, data in reversed(records):  # oldest copy of a byte wins
                raw.seek(off)
                raw.write(data)
            raw.truncate(size0)
            raw.flush()
            if fsync:
                os.fsync(raw.fileno())
    # a journal without a valid header was torn before any in-place write: nothing to undo
    jpath.unlink()
    if fsync:
        _fsync_dir(path)


def recover(path: Path, wait_s: float, fsync: bool = True) -> None:
    """Roll back an interrupted write session of ``path`` if one left a journal."""
    if not journal_path(path).exists():
        return
    try:
        raw = open(path, "r+b", buffering=0)  # noqa: SIM115
    except PermissionError:
        raise ValueError(f"{path} has an interrupted write ({journal_path(path).name}); "
                         "open it once with write access to roll it back") from None
    with raw:
        _lock(raw.fileno(), path, wait_s)
        _rollback(raw, path, fsync)


class JournaledFile:
    """Binary file object for ``h5py.File``: journals original bytes before overwriting them."""

    def __init__(self, raw, path: Path, fsync: bool) -> None:
        self._raw, self._fsync = raw, fsync
        self._size0 = os.fstat(raw.fileno()).st_size
        self._saved: set[tuple[int, int]] = set()
        self._journal = open(journal_path(path), "wb", buffering=0)  # noqa: SIM115
        head = _HEAD.pack(MAGIC, self._size0, 0)[:-4]
        self._append(head + struct.pack("<I", zlib.crc32(head)))

    def _append(self, blob: bytes) -> None:
        self._journal.write(blob)
        if self._fsync:
            os.fsync(self._journal.fileno())

    def _save(self, start: int, end: int) -> None:
        end = min(end, self._size0)
        if start >= end or (start, end) in self._saved:
            return
        here = self._raw.tell()
        self._raw.seek(start)
        data = self._raw.read(end - start)
        self._raw.seek(here)
        self._append(_REC.pack(start, len(data), zlib.crc32(data)) + data)
        self._saved.add((start, end))

    # file protocol used by h5py's fileobj driver
    def seek(self, pos: int, whence: int = 0) -> int:
        return self._raw.seek(pos, whence)

    def tell(self) -> int:
        return self._raw.tell()

    def read(self, n: int = -1) -> bytes:
        return self._raw.read(n)

    def readinto(self, buf) -> int:
        return self._raw.readinto(buf)

    def write(self, data) -> int:
        n = memoryview(data).nbytes
        pos = self._raw.tell()
        self._save(pos, pos + n)
        return self._raw.write(data)

    def truncate(self, size: int | None = None) -> int:
        size = self._raw.tell() if size is None else size
        self._save(size, self._size0)
        return self._raw.truncate(size)

    def flush(self) -> None:
        self._raw.flush()

    def close_journal(self) -> None:
        self._journal.close()


@contextmanager
def journaled(path: Path, wait_s: float, fsync: bool) -> Iterator[JournaledFile]:
    """Exclusive write session on ``path``: committed on success, rolled back on any error or kill."""
    with open(path, "r+b", buffering=0) as raw:
        _lock(raw.fileno(), path, wait_s)
        _rollback(raw, path, fsync)  # a previous writer was killed mid-session
        jf = JournaledFile(raw, path, fsync)
        try:
            yield jf
        except BaseException:
            jf.close_journal()
            _rollback(raw, path, fsync)
            raise
        jf.close_journal()
        if fsync:
            os.fsync(raw.fileno())
        journal_path(path).unlink()  # commit point
        if fsync:
            _fsync_dir(path)
