"""Ctrl-C (SIGINT) and SIGTERM as ends, not crashes.

A long loop (``collect``, a training run) runs inside :func:`stop_requests`: the first SIGINT or SIGTERM only sets
``request.signum``, and the loop checks it where stopping is safe (between env steps, between optimiser steps), drops
what is in flight, keeps what is finished (the writer drained, a resume point saved) and raises :class:`Interrupted`:
one line saying what was kept and where; the command line prints it and exits 128 + the signal (130, 143). A second
signal raises ``KeyboardInterrupt`` at once. Outside the main thread (a Prefect or Dask worker's thread) the signals
are left as they are: only the main thread may handle them.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that ask a run to stop."""


class Interrupted(KeyboardInterrupt):
    """A run stopped by SIGINT / SIGTERM after keeping what it had finished; the message is one line (what was kept,
    where, how to go on)."""

    def __init__(self, message: str, signum: int = signal.SIGINT) -> None:
        super().__init__(message)
        self.signum = int(signum)

    @property
    def exit_status(self) -> int:
        """The shell's status of a process ended by the signal: 130 for SIGINT, 143 for SIGTERM."""
        return 128 + self.signum


class StopRequest:
    """Set by the first SIGINT / SIGTERM inside :func:`stop_requests`."""

    signum: int | None = None

    def __bool__(self) -> bool:
        return self.signum is not None


@contextmanager
def stop_requests() -> Iterator[StopRequest]:
    """Within: SIGINT and SIGTERM set the yielded request instead of raising (a second one raises
    ``KeyboardInterrupt``); the previous handlers come back at the end. A no-op off the main thread."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def handler(signum, frame):
        if request.signum is not None:
            raise KeyboardInterrupt
        request.signum = signum

    previous = {s: signal.signal(s, handler) for s in SIGNALS}
    try:
        yield request
    finally:
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
