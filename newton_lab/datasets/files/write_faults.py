"""Test seam: a full or failing disk on demand. Every low-level write of both stores calls
:func:`write_fault_point`; a test arms it with :func:`inject_write_fault`, in its own process or in a child process it
starts (its launcher calls it), and the armed write and every later one raise ``OSError``. Nothing arms it in a
product run: no environment variable or file does."""

from __future__ import annotations

import errno
import os
import threading

_fault_lock = threading.Lock()
_fault: dict[str, int | None] = {"left": None, "errno": errno.ENOSPC}


def inject_write_fault(fail_at: int | None, err: int = errno.ENOSPC) -> None:
    """Test seam: the ``fail_at``-th low-level dataset write from now on raises ``OSError(err)``, and so
    does every later one (a full disk stays full); ``None`` clears it. Armed in this process only."""
    if fail_at is not None and fail_at < 1:
        raise ValueError(f"fail_at must be >= 1, got {fail_at}")
    with _fault_lock:
        _fault.update(left=None if fail_at is None else fail_at - 1, errno=err)


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
