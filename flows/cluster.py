"""The pipeline's Dask task runner: a local cluster of worker processes, or the scheduler at ``address``.

How the local cluster is sized:

- ``device`` None or ``"cuda"`` on a host with CUDA devices: one worker process per GPU, at most ``workers``
  of them; worker ``i`` sees only the ``i``-th visible GPU (``CUDA_VISIBLE_DEVICES``, so its ``cuda`` /
  ``cuda:0`` is that GPU). ``workers`` beyond the GPU count add shards, not workers: the extra shards wait
  for a free GPU.
- any other device (``cpu``, a named ``cuda:N``) or no CUDA device: ``workers`` processes, all on that device.

Each worker runs one stage at a time (one thread); the GPUs seen are those of ``CUDA_VISIBLE_DEVICES`` when
it is set, else all that Warp finds.
"""

from __future__ import annotations

import functools
import logging
import os
from typing import Any

NANNY_CLOSE_S = 30.0
"""Seconds a worker process gets to stop at cluster shutdown (killed after 0.8x, then as long again to be reaped).
distributed's 5 s ran out on a loaded 2-core host, and its TimeoutError then replaced the run's own result."""

SCHEDULER_HTTP = "127.0.0.1:0"
"""Where the scheduler's HTTP endpoint (health and metrics; the dashboard is off) listens: a free local port, so a
second cluster on the host, or a dashboard already on distributed's 8787, neither clashes nor warns."""


WORKER_LOG_LEVEL = logging.CRITICAL
"""Level of distributed's own log lines that the local cluster's processes print. A stage's failure reaches the
flow (and the one-line error) through its task run, not through these; on a busy host a worker's heartbeat
that races the scheduler's shutdown logs a traceback at ERROR, after the pipeline has already answered."""


def visible_gpus() -> list[str]:
    """CUDA device ids this process may use: ``CUDA_VISIBLE_DEVICES``'s entries, else ``0..n-1`` for Warp's
    CUDA device count (empty without a driver)."""
    env = os.environ.get("CUDA_VISIBLE_DEVICES")
    if env is not None:
        ids = [d.strip() for d in env.split(",") if d.strip()]
        return [] if not ids or ids[0].startswith("-") else ids
    import warp as wp  # deferred: Warp is slow to import (already loaded by the task registry here)

    return [str(i) for i in range(wp.get_cuda_device_count())]


def pins_gpus(device: str | None) -> bool:
    """Whether stages on ``device`` take one GPU per worker (None and ``"cuda"``: any GPU will do)."""
    return device is None or device == "cuda"


def cluster_options(workers: int, device: str | None, gpus: list[str] | None = None) -> dict[str, Any]:
    """``DaskTaskRunner`` keywords of a local cluster sized as the module docstring says (``gpus``: the
    visible CUDA device ids, looked up when None)."""
    if pins_gpus(device):
        gpus = visible_gpus() if gpus is None else gpus
    if gpus and pins_gpus(device):
        from distributed import Scheduler, SpecCluster  # deferred: Dask is slow to import

        nanny = _patient_nanny()
        spec = {
            f"gpu-{gpu}": {
                "cls": nanny,
                "options": {
                    "nthreads": 1,
                    "env": {"CUDA_VISIBLE_DEVICES": gpu},
                    "silence_logs": WORKER_LOG_LEVEL,
                    "dashboard": False,
                },
            }
            for gpu in gpus[:workers]
        }
        return {
            "cluster_class": SpecCluster,
            "cluster_kwargs": {
                "workers": spec,
                "scheduler": {"cls": Scheduler, "options": {"dashboard": False, "dashboard_address": SCHEDULER_HTTP}},
                "silence_logs": WORKER_LOG_LEVEL,
            },
        }
    return {
        "cluster_kwargs": {
            "n_workers": workers,
            "processes": True,
            "threads_per_worker": 1,
            "worker_class": _patient_nanny(),
            "dashboard_address": None,
            "silence_logs": WORKER_LOG_LEVEL,
            "scheduler_kwargs": {"dashboard_address": SCHEDULER_HTTP},
        }
    }


@functools.cache
def _patient_nanny() -> type:
    """distributed's ``Nanny`` whose ``close`` waits at least ``NANNY_CLOSE_S`` (a class made on first use: Dask is
    slow to import)."""
    from distributed import Nanny  # deferred: Dask is slow to import

    class PatientNanny(Nanny):
        async def close(self, timeout: float = NANNY_CLOSE_S, reason: str = "nanny-close"):
            return await super().close(timeout=max(timeout, NANNY_CLOSE_S), reason=reason)

    return PatientNanny


class _SlowExit(logging.Filter):
    """Drops the nanny's 'Worker process still alive after 4.0 seconds, killing' at cluster shutdown: a worker
    that imported torch, Warp and Prefect can take longer than that to exit on a busy host, and by then its
    results are back."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not record.getMessage().startswith("Worker process still alive after")


def quiet_shutdown() -> None:
    """Install ``_SlowExit`` on the ``distributed.nanny`` logger of this process (once)."""
    nanny = logging.getLogger("distributed.nanny")
    if not any(isinstance(f, _SlowExit) for f in nanny.filters):
        nanny.addFilter(_SlowExit())
