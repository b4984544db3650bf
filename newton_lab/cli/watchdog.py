"""A watchdog on a command's pid: when the command ends, even by SIGKILL, the processes it started end too.

``newton-lab pipeline`` starts processes it does not own the start of: Prefect's embedded server (uvicorn, which
Prefect's ephemeral mode starts), Dask workers, and the children of its stages (a writer process, torchrun). A
child that the kernel does not end with its parent would run on as an orphan. :func:`start` runs this file as a
script (standard library only: it starts in a few tens of milliseconds and imports nothing of the project) in a
session of its own (a Ctrl-C at the terminal does not reach it). It notes the command's descendants every
``POLL_S`` seconds; once the command is gone (its parent pid changes), it ends every one of them still running:
SIGTERM, then SIGKILL after ``GRACE_S``, then it exits. Linux only (``/proc``); a no-op elsewhere.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

POLL_S = 0.1
"""Seconds between two looks at the command's processes (and at whether it still runs)."""
GRACE_S = 0.5
"""Seconds a process is given to end on SIGTERM before SIGKILL."""


def children(pid: int) -> list[int]:
    """The pids of ``pid``'s children (``/proc/<pid>/task/*/children``); none when it is gone."""
    out: list[int] = []
    try:  # the process may end between two reads: its /proc folder is then gone
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for task in tasks:
        try:
            out += [int(c) for c in Path(f"/proc/{pid}/task/{task}/children").read_text().split()]
        except OSError:
            pass
    return out


def descendants(pid: int) -> list[int]:
    """Children of ``pid``, theirs, and so on."""
    return [d for c in children(pid) for d in (c, *descendants(c))]


def start_time(pid: int) -> int | None:
    """The process's start time in clock ticks since boot (tells a process from a later one given its pid); None
    when there is no such process or it is a zombie."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return None if fields[0] == "Z" else int(fields[19])


def start() -> subprocess.Popen | None:
    """Watch this process from a process of its own; None off Linux."""
    if not sys.platform.startswith("linux"):
        return None
    return subprocess.Popen(
        [sys.executable, "-S", "-I", __file__, str(os.getpid())],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        close_fds=True,
    )


def end(pids: dict[int, int | None]) -> None:
    """SIGTERM every process of ``pids`` (pid: start time) that is still the same one, SIGKILL those left after
    ``GRACE_S``."""
    live = {p: t for p, t in pids.items() if t is not None and start_time(p) == t}
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for pid in live:
            try:
                os.kill(pid, sig)
            except OSError:
                pass
        deadline = time.monotonic() + GRACE_S
        while sig == signal.SIGTERM and time.monotonic() < deadline:
            live = {p: t for p, t in live.items() if start_time(p) == t}
            if not live:
                return
            time.sleep(0.02)


def watch(parent: int) -> None:
    """Note ``parent``'s descendants until it ends, then end those still running (and theirs)."""
    me = os.getpid()
    known: dict[int, int | None] = {}
    while os.getppid() == parent:
        for pid in descendants(parent):
            if pid != me and pid not in known:
                known[pid] = start_time(pid)
        time.sleep(POLL_S)
    doomed = dict(known)
    for pid, began in known.items():  # what they started since the last look is still below them
        if began is not None and start_time(pid) == began:
            doomed.update({d: start_time(d) for d in descendants(pid)})
    doomed.pop(me, None)
    end(doomed)


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    watch(int(sys.argv[1]))
