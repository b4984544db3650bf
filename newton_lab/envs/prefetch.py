"""Compile the env step's large Warp modules on a second thread while the first builds the model.

Warp compiles a module when one of its kernels is first launched, one after another on one thread: a cold
``make_env`` on 2 CPU cores spends ~150 s there and leaves the other core idle. The modules below are imported
before the model is built but launched only later (solver set-up, the first step, the planner's IK), so a
background ``wp.load_module`` of each runs beside the model build and its compile is done when the step needs
it. Warp's codegen holds a lock; the C++/LLVM compile itself runs in parallel. Measured on this 2-core CPU with
a cold kernel cache: ``make_env`` + a 4-episode PickCube collect 159 s -> 139 s with the newton / newton_lab
modules alone; the list below adds mujoco_warp's. A module the main thread reaches first is simply compiled
there (the cache write is atomic either way); nothing here changes what is compiled, only when.

On a CUDA device of a host with more cores (a GPU machine has 16), the modules compile side by side
(``wp.force_load``'s thread pool, ``prefetch_workers``): the compiler runs outside Python, one module per worker.
A cold PickToShelf env build with two 96x72 views took 110 s on an H200 host with the one prefetch thread.
"""

from __future__ import annotations

import logging
import os
import sys
import threading

import warp as wp

PREFETCH_MODULES = (
    "mujoco_warp._src.set_const",
    "mujoco_warp._src.smooth",
    "newton_lab.kernels.fuse",
    "newton_lab.kernels.actions",
    "newton._src.sim.articulation",
    "newton_lab.kernels.context",
    "mujoco_warp._src.constraint",
    "mujoco_warp._src.forward",
    "mujoco_warp._src.passive",
    "mujoco_warp._src.support",
    "mujoco_warp._src.solver",
    "mujoco_warp._src.derivative",
    "newton._src.sim.ik.ik_common",
    "newton._src.sim.ik.ik_objectives",
    "newton._src.sim.ik.ik_solver",
)
"""Modules in the order the env first launches them (``make_env`` -> first step -> planner), each compiling for
a second or more (the ~1 s ones are left to the main thread). Names missing in this Newton version are skipped."""

_started: set[str] = set()
_lock = threading.Lock()
log = logging.getLogger(__name__)


def prefetch_kernels(device: str | None) -> None:
    """Start compiling ``PREFETCH_MODULES`` for ``device`` on a daemon thread (once per process and device)."""
    key = str(wp.get_device(device))
    with _lock:
        if key in _started:
            return
        _started.add(key)
    # Imported here, on the caller's thread: an import on the prefetch thread raced the solver's own import of
    # mujoco_warp, and Python's import-deadlock breaker then handed one thread a half-initialised module
    # ("module 'mujoco_warp' has no attribute 'OverflowType'" in a Dask worker). Importing defines kernels and
    # compiles nothing, so the thread below still takes all the compile time.
    import mujoco_warp  # noqa: F401  deferred: only an env build needs it

    threading.Thread(target=_load_all, args=(key,), name="newton_lab-kernel-prefetch", daemon=True).start()


def prefetch_workers(on_cpu: bool, cores: int | None = None) -> int:
    """Modules compiled at once: one for a CPU device (its compile shares the cores the model build needs), else
    up to 8, leaving one of the host's ``cores`` (default: all of them) to the model build."""
    cores = (os.cpu_count() or 1) if cores is None else cores
    return 1 if on_cpu else max(1, min(8, cores - 1))


def _load_all(device: str, workers: int | None = None) -> list[str]:
    """Compile (or load from the cache) ``PREFETCH_MODULES`` on ``device``; the names of those imported."""
    workers = prefetch_workers(wp.get_device(device).is_cpu) if workers is None else workers
    names = [name for name in PREFETCH_MODULES if name in sys.modules]
    if workers > 1:
        try:
            wp.force_load(device=device, modules=[wp.get_module(name) for name in names], max_workers=workers)
            return names
        except Exception as exc:  # noqa: BLE001  an optimisation only: the main thread compiles what it must
            log.debug("parallel kernel prefetch stopped: %s", exc)
    for name in names:
        try:
            wp.load_module(name, device=device, max_workers=0)
        except Exception as exc:  # noqa: BLE001  an optimisation only: the main thread compiles it when it must
            log.debug("kernel prefetch of %s skipped: %s", name, exc)
    return names
