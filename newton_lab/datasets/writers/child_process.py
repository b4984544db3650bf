"""Child processes of the writers: started on this process's import path, answering on a private pipe, and ended by
the kernel when their parent ends."""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
from typing import Any


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
