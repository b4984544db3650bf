"""Rollback journal that makes in-place edits of one file atomic (used for HDF5 appends).

HDF5 has no atomic commit: a writer killed while the library flushes its metadata cache can
leave dangling links or overlapping allocations. So every write session goes through
:class:`JournaledFile`: before a byte that existed when the session started is overwritten,
its original content is appended to ``<file>-journal``. Deleting the journal is the commit;
a journal found later (writer killed) is rolled back, restoring the last committed file.
An exclusive ``flock`` on the data file (the lock HDF5 itself uses) serialises sessions.
"""

from __future__ import annotations

import os
import struct
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..files.locking import lock_exclusive
from ..files.write_faults import write_fault_point

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


def _rollback(raw, path: Path, fsync: bool) -> None:
    """Undo an interrupted session recorded in the journal (idempotent), then drop the journal."""
    jpath = journal_path(path)
    try:
        blob = jpath.read_bytes()
    except FileNotFoundError:
        return
    if len(blob) >= _HEAD.size:
        magic, size0, crc = _HEAD.unpack_from(blob)
        if magic == MAGIC and crc == zlib.crc32(blob[: _HEAD.size - 4]):
            records, pos = [], _HEAD.size
            while pos + _REC.size <= len(blob):
                off, n, rcrc = _REC.unpack_from(blob, pos)
                data = blob[pos + _REC.size : pos + _REC.size + n]
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
        raise ValueError(
            f"{path} has an interrupted write ({journal_path(path).name}); "
            "open it once with write access to roll it back"
        ) from None
    with raw:
        lock_exclusive(raw.fileno(), path, wait_s)
        _rollback(raw, path, fsync)


def _write_all(f, data) -> None:
    """Write every byte (an unbuffered write may be short just before ENOSPC)."""
    view = memoryview(data).cast("B")
    while view.nbytes:
        write_fault_point()
        view = view[f.write(view) :]


class JournaledFile:
    """Binary file object for ``h5py.File``: journals original bytes before overwriting them.

    If the disk refuses a write (ENOSPC, EIO), HDF5 is not told (it answers a failing driver with
    tracebacks and, at close, a crash): the error is kept in ``error``, and the rest of the session
    goes to memory, so HDF5 finishes against a consistent view; :func:`journaled` then raises
    ``error`` and rolls the file back.
    """

    def __init__(self, raw, path: Path, fsync: bool) -> None:
        self._raw, self._fsync = raw, fsync
        self._size0 = os.fstat(raw.fileno()).st_size
        self._saved: set[tuple[int, int]] = set()
        self.error: OSError | None = None
        self._mem: list[tuple[int, bytes]] = []  # writes after the error: (offset, bytes)
        self._pos = self._len = self._valid = 0  # position, size, bytes of raw still valid (after the error)
        self._journal = open(journal_path(path), "wb", buffering=0)  # noqa: SIM115
        head = _HEAD.pack(MAGIC, self._size0, 0)[:-4]
        try:
            self._append(head + struct.pack("<I", zlib.crc32(head)))
        except BaseException:
            self._journal.close()
            raise

    def _append(self, blob: bytes) -> None:
        _write_all(self._journal, blob)
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

    def _fail(self, error: OSError, pos: int) -> None:
        self.error, self._pos = error, pos
        self._len = self._valid = os.fstat(self._raw.fileno()).st_size

    def _read_failed(self, n: int) -> bytes:
        start = self._pos
        end = self._len if n is None or n < 0 else min(self._len, start + n)
        buf = bytearray(max(0, end - start))
        if start < min(end, self._valid):
            self._raw.seek(start)
            got = self._raw.read(min(end, self._valid) - start)
            buf[: len(got)] = got
        for off, blob in self._mem:
            lo, hi = max(off, start), min(off + len(blob), end)
            if lo < hi:
                buf[lo - start : hi - start] = blob[lo - off : hi - off]
        self._pos = start + len(buf)
        return bytes(buf)

    # file protocol used by h5py's fileobj driver
    def seek(self, pos: int, whence: int = 0) -> int:
        if self.error is None:
            return self._raw.seek(pos, whence)
        self._pos = (0, self._pos, self._len)[whence] + pos
        return self._pos

    def tell(self) -> int:
        return self._raw.tell() if self.error is None else self._pos

    def read(self, n: int = -1) -> bytes:
        return self._raw.read(n) if self.error is None else self._read_failed(n)

    def readinto(self, buf) -> int:
        if self.error is None:
            return self._raw.readinto(buf)
        data = self._read_failed(memoryview(buf).nbytes)
        memoryview(buf).cast("B")[: len(data)] = data
        return len(data)

    def write(self, data) -> int:
        n = memoryview(data).nbytes
        if self.error is None:
            pos = self._raw.tell()
            try:
                self._save(pos, pos + n)
                _write_all(self._raw, data)
                return n
            except OSError as e:
                self._fail(e, pos)
        self._mem.append((self._pos, bytes(memoryview(data).cast("B"))))
        self._pos += n
        self._len = max(self._len, self._pos)
        return n

    def truncate(self, size: int | None = None) -> int:
        size = self.tell() if size is None else size
        if self.error is None:
            try:
                self._save(size, self._size0)
                return self._raw.truncate(size)
            except OSError as e:
                self._fail(e, self._raw.tell())
        self._len, self._valid = size, min(self._valid, size)
        self._mem = [(off, blob[: size - off]) for off, blob in self._mem if off < size]
        return size

    def flush(self) -> None:
        if self.error is None:
            self._raw.flush()

    def close_journal(self) -> None:
        self._journal.close()


def _abort(raw, path: Path, fsync: bool, jf: JournaledFile | None) -> None:
    """Roll back a failed session; if even that fails, the journal stays for the next opener."""
    if jf is not None:
        jf.close_journal()
    try:
        _rollback(raw, path, fsync)
    except OSError:
        pass


@contextmanager
def journaled(path: Path, wait_s: float, fsync: bool) -> Iterator[JournaledFile]:
    """Exclusive write session on ``path``: committed on success, rolled back on any error or kill."""
    with open(path, "r+b", buffering=0) as raw:
        lock_exclusive(raw.fileno(), path, wait_s)
        _rollback(raw, path, fsync)  # a previous writer was killed mid-session
        jf = None
        try:
            jf = JournaledFile(raw, path, fsync)
            yield jf
            if jf.error is not None:
                raise jf.error
            jf.close_journal()
            if fsync:
                os.fsync(raw.fileno())
        except BaseException:
            _abort(raw, path, fsync, jf)
            raise
        journal_path(path).unlink()  # commit point
        if fsync:
            _fsync_dir(path)
