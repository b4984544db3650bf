"""Stage faults for the flow tests, through the pipeline's stage-start hook (``runlog.STAGE_START_HOOKS``).

A spec ``<stage>:<kind>:<marker file>[,...]``: the first time ``stage`` starts (``marker file`` does not exist yet; it
is created), ``kind`` ``oserror`` raises a transient ``OSError(EIO)`` and ``kill`` SIGKILLs the process running the
stage (a lost Dask worker). :func:`armed` arms it in this process (the default runner's stages run here); on a local
Dask cluster each worker process arms itself as it starts (:func:`dask_setup`, a Dask worker preload, reading the spec
from ``SPEC_ENV`` in its environment). The library reads neither.
"""

from __future__ import annotations

import errno
import os
import signal
from collections.abc import Iterator
from contextlib import contextmanager

SPEC_ENV = "NEWTON_LAB_TEST_STAGE_FAULT"
"""Where a Dask worker finds the spec (set by the test before the cluster starts; read only by this module)."""


def injector(spec: str):
    """The stage-start hook that injects the faults of ``spec``, each once."""

    def inject(stage: str) -> None:
        for item in spec.split(","):
            name, kind, marker = item.split(":", 2)
            if name != stage:
                continue
            try:
                os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            except FileExistsError:
                continue  # injected once already: this is the retry
            if kind == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
            raise OSError(errno.EIO, f"injected transient I/O error in stage {stage}")

    return inject


@contextmanager
def armed(spec: str, dask_workers: bool = False) -> Iterator[None]:
    """Within: the faults of ``spec`` fire in this process, and (``dask_workers``) in the worker processes of a local
    Dask cluster started within (a worker preload: this file)."""
    from newton_lab.flows import runlog  # deferred: imports Prefect (after the test harness configured it)

    hook = injector(spec)
    runlog.STAGE_START_HOOKS.append(hook)
    previous = os.environ.get(SPEC_ENV)
    try:
        if not dask_workers:
            yield
            return
        import dask
        import distributed  # noqa: F401  (its config defaults first: leaving the ``set`` below restores them)

        os.environ[SPEC_ENV] = spec
        with dask.config.set({"distributed.worker.preload": [__file__]}):
            yield
    finally:
        runlog.STAGE_START_HOOKS.remove(hook)
        if previous is None:
            os.environ.pop(SPEC_ENV, None)
        else:
            os.environ[SPEC_ENV] = previous


def dask_setup(worker) -> None:
    """Dask worker preload: arm the spec of ``SPEC_ENV`` in this worker process."""
    spec = os.environ.get(SPEC_ENV)
    if spec:
        from newton_lab.flows import runlog

        runlog.STAGE_START_HOOKS.append(injector(spec))
