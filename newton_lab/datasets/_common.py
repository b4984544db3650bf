"""Helpers shared by the HDF5 and zarr episode stores."""

from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import math
import os
import re
import subprocess
import sys
import threading
import time
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
LOCK_WAIT_S = 10.0  # bounded wait for the writer lock (both formats)
TURNSTILE = 1 << 62  # byte offset of the writers' fairness lock


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


def damaged(path: Path, reason: str) -> ValueError:
    """One-line error for a path that does not hold a readable dataset."""
    reason = " ".join(str(reason).split())[:200]
    return ValueError(
        f"{path} is not a newton_lab dataset or is damaged ({reason}); it was left untouched: "
        "re-collect the episodes into a new path (or restore a backup)")


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


# ----------------------------------------------------------------------------- writer protocol
class DatasetLockedError(BlockingIOError, ValueError):
    """Another process kept the dataset locked past the bounded wait (one line; also a ``ValueError``)."""


class DatasetWriteError(OSError):
    """The disk refused a write (ENOSPC, EIO, ...): one line saying what the dataset still holds."""

    def __init__(self, message: str, err: int) -> None:
        super().__init__(message)
        self.errno = err

    def __reduce__(self):  # crosses process boundaries (a phase writer of split): both arguments
        return type(self), (self.args[0], self.errno)


STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.EROFS})
"""OS errors of the medium that end a write session as a :class:`DatasetWriteError`."""


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


# ----------------------------------------------------------------------------- fault injection (tests)
_FAULT_ENV = "NEWTON_LAB_TEST_WRITE_FAULT"
_fault_lock = threading.Lock()
_fault: dict[str, int | None] = {"left": None, "errno": errno.ENOSPC}


def inject_write_fault(fail_at: int | None, err: int = errno.ENOSPC) -> None:
    """Test seam: the ``fail_at``-th low-level dataset write from now on raises ``OSError(err)``, and so
    does every later one (a full disk stays full); ``None`` clears it. Subprocesses started by pytest
    read ``NEWTON_LAB_TEST_WRITE_FAULT=<fail_at>[:<errno name>]`` (honoured only under pytest)."""
    if fail_at is not None and fail_at < 1:
        raise ValueError(f"fail_at must be >= 1, got {fail_at}")
    with _fault_lock:
        _fault.update(left=None if fail_at is None else fail_at - 1, errno=err)


def fault_injected() -> bool:
    """Whether a test fault is armed (writes then stay in this process, where the fault lives)."""
    with _fault_lock:
        return _fault["left"] is not None


def write_fault_point() -> None:
    """Called before every low-level write of both stores; raises the injected fault, if any."""
    with _fault_lock:
        left, err = _fault["left"], _fault["errno"]
        if left is None:
            return
        if left > 0:
            _fault["left"] = left - 1
            return
    raise OSError(err, os.strerror(err))


def _fault_from_env() -> None:
    spec = os.environ.get(_FAULT_ENV)
    if spec and "PYTEST_CURRENT_TEST" in os.environ:
        at, _, name = spec.partition(":")
        inject_write_fault(int(at), getattr(errno, name or "ENOSPC"))


_fault_from_env()


def child_pipes():
    """(stdin, the original stdout) of a child process that answers its parent on stdout, as binary files; fd 1 then
    points to stderr, so that nothing printed, by Python or a library, can corrupt the answers."""
    src, dst = sys.stdin.buffer, os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    return src, dst


def start_child(module: str, function: str, *args: str, **popen: Any) -> subprocess.Popen:
    """A Python process running ``module.function()`` (``args`` in its ``sys.argv[1:]``) on this process's import path,
    so that it runs this very package wherever the caller was started from; stdin and stdout piped (the child answers
    through :func:`child_pipes`)."""
    command = [sys.executable, "-c", f"from {module} import {function}; {function}()", *args]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    return subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env, **popen)


PR_SET_PDEATHSIG = 1
"""``prctl`` option: the signal the kernel sends this process when the thread that started it ends (Linux)."""


def die_with_parent(parent: int | None = None, sig: int = 9) -> None:
    """Have the kernel send this process ``sig`` (SIGKILL by default) when its parent ends, even by SIGKILL: a child
    (a phase writer of ``split``, the torchrun of a data-parallel ``train``) is never left running as an orphan. For
    a pool initializer or a ``preexec_fn``; ``parent``: the pid the caller expects as parent (a parent that ended
    before the signal was set is caught by comparing it). No-op off Linux."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0)
    except (OSError, AttributeError):
        return
    if parent is not None and os.getppid() != parent:  # the parent ended already: no signal will come
        os.kill(os.getpid(), sig)
