"""How ``newton-lab pipeline`` ends when it is stopped: Ctrl-C (SIGINT) or SIGTERM ends it at once with one line
(the stages that finished, where; the same command resumes from them) and exit status 130 / 143; SIGKILL leaves no
process of its own running (a watchdog ends the embedded Prefect server, Dask workers and stage children).

A stage in flight when the signal lands is dropped: it has written no manifest, so the next run removes what it
had begun (``flows.stages._fresh``) and runs it again; every finished stage has its manifest and is answered from
it. The stage runs in a worker thread of Prefect's task runner, which no signal reaches and which Python would wait
for at exit (minutes for a training), so the process ends from the signal handler itself.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from . import watchdog


def finished_stages(out: str | os.PathLike) -> list[str]:
    """The stages ``out`` holds finished (a ``<name>.manifest.json`` beside the output), in the order they ended."""
    manifests = [p for p in Path(out).rglob("*.manifest.json") if not p.name.startswith(".")]
    manifests.sort(key=lambda p: p.stat().st_mtime)
    return [str(p.relative_to(out))[: -len(".manifest.json")] for p in manifests]


def interrupted_line(out: str | os.PathLike) -> str:
    """The line of a pipeline stopped by a signal: what finished, where, and how to go on."""
    try:
        done = finished_stages(out)
    except OSError:
        done = []
    if not done:
        return f"newton-lab pipeline: interrupted before any stage finished; nothing kept in {out}"
    return (
        f"newton-lab pipeline: interrupted: finished stages kept in {out}: {', '.join(done)}; the same command "
        "resumes from them"
    )


@contextmanager
def ends_in_one_line(out: str | os.PathLike) -> Iterator[None]:
    """Within: a watchdog ends this process's children when it ends (even by SIGKILL), and SIGINT / SIGTERM end it
    with :func:`interrupted_line` on stderr and exit status 128 + the signal."""
    watchdog.start()

    def stop(signum, frame):
        sys.stdout.flush()
        os.write(2, (interrupted_line(out) + "\n").encode())
        os._exit(128 + signum)  # the watchdog ends the children: the server, workers, a stage's processes

    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
