"""SIGTERM as Ctrl-C: while a command runs, SIGTERM (``kill``, a scheduler's stop, ``timeout``) raises
:class:`Terminated`, a ``KeyboardInterrupt``, in the main thread, so that every command ends on it as it ends on
Ctrl-C: what it finished is kept, its children stopped, one line printed, and exit status 143 (where Python's default
would end the process on the spot, leaving a split's stage folder and printing nothing). Loops that stop between two
steps (``datasets.writers.interrupts.stop_requests``) and the pipeline (``pipeline_ends``) install their own handler
for the time they run."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager


class Terminated(KeyboardInterrupt):
    """The command was sent SIGTERM."""

    signum = int(signal.SIGTERM)
    exit_status = 128 + int(signal.SIGTERM)


def _raise(signum, frame) -> None:
    raise Terminated("interrupted (SIGTERM)")


@contextmanager
def sigterm_as_ctrl_c() -> Iterator[None]:
    """Within: SIGTERM raises :class:`Terminated` (a no-op off the main thread, where no handler can be set)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)
