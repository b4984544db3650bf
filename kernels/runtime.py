"""Warp's process-wide settings for newton_lab: no adjoint kernels, and quiet start-up output.

No backward kernels: newton_lab never differentiates through Warp (the planner's IK uses analytic Jacobians,
policies train in torch), yet Warp generates and compiles every kernel's adjoint unless told otherwise, and
Newton's modules take Warp's global default. ``install()`` sets ``wp.config.enable_backward = False`` as soon as
Warp is imported, so every module created after it (Newton's, mujoco_warp's generated ones, the fused task
kernels) compiles forward code only. The fused StackCube task kernel's CUDA build (NVRTC, sm_90) went from
more than 25 minutes to 24 s (``tools/cuda_compile_cost.py``). ``NEWTON_LAB_WARP_BACKWARD=1`` keeps Warp's
default, for users who differentiate their own kernels next to newton_lab; a module created before
``import newton_lab`` keeps the setting it was created with.

Quiet: without it a run prints Warp's init banner, one ``Module ... load on device ... took ...`` line per kernel
module (~70 before an example starts) and, on a machine without an NVIDIA driver, ``Warp CUDA warning:
Could not find or load the NVIDIA CUDA driver`` (printed by Warp's C library on stderr). ``install()``
(called by ``import newton_lab``) makes Warp quiet as soon as Warp is imported, in every process that
imports newton_lab (CLI, examples, Dask workers, tests): ``config.quiet``, log level WARNING, and that one
driver line dropped when no driver can be loaded (every other line of Warp's init is passed through).
``NEWTON_LAB_VERBOSE=1`` (``newton-lab --verbose``) keeps Warp's own output.

This module imports nothing heavy: ``install()`` costs no Warp import.
"""

from __future__ import annotations

import ctypes
import importlib.abc
import importlib.machinery
import os
import sys
import tempfile

VERBOSE_ENV = "NEWTON_LAB_VERBOSE"
"""Environment variable: ``1`` keeps Warp's banner, module-load lines and driver warning."""
DRIVER_LINE = "Could not find or load the NVIDIA CUDA driver"
"""The part of Warp's no-driver warning that identifies it."""
_DRIVER_LIBS = ("libcuda.so", "libcuda.so.1", "nvcuda.dll")


BACKWARD_ENV = "NEWTON_LAB_WARP_BACKWARD"
"""Environment variable: ``1`` keeps Warp's default of compiling every kernel's adjoint (backward) code."""


def keep_backward() -> bool:
    """Whether the user asked to keep Warp's adjoint kernels (``NEWTON_LAB_WARP_BACKWARD`` set to 1/true/yes)."""
    return os.environ.get(BACKWARD_ENV, "").strip().lower() in ("1", "true", "yes")


def verbose() -> bool:
    """Whether the user asked for Warp's own output (``NEWTON_LAB_VERBOSE`` set to 1/true/yes)."""
    return os.environ.get(VERBOSE_ENV, "").strip().lower() in ("1", "true", "yes")


def has_cuda_driver() -> bool:
    """Whether the NVIDIA driver library can be loaded (what Warp's init looks for)."""
    for name in _DRIVER_LIBS:
        try:
            ctypes.CDLL(name)
            return True
        except OSError:
            continue
    return False


def _init_without_driver_line(wp) -> None:
    """``wp.init()`` with stderr captured at the file-descriptor level (the warning comes from C); every
    captured line but the driver warning is written back to stderr."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        kept = [
            line for line in tmp.read().decode(errors="replace").splitlines(keepends=True) if DRIVER_LINE not in line
        ]
    if kept:
        sys.stderr.write("".join(kept))
        sys.stderr.flush()


def quiet_warp(wp=None) -> None:
    """Make Warp quiet now (no banner, no module-load lines, no driver warning without a driver), unless
    ``NEWTON_LAB_VERBOSE=1``. ``wp``: the imported ``warp`` module (imported here when omitted)."""
    if verbose():
        return
    if wp is None:
        import warp as wp  # deferred: Warp is slow to import and this module must stay cheap

    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    if wp._src.context.runtime is None:  # Warp has no public "is initialised"; init() is idempotent anyway
        if has_cuda_driver():
            wp.init()
        else:
            _init_without_driver_line(wp)


def set_verbose() -> None:
    """Show Warp's output from now on, in this process and the ones it starts (``NEWTON_LAB_VERBOSE=1``);
    a Warp already initialised quietly shows its module-load lines from here on."""
    os.environ[VERBOSE_ENV] = "1"
    wp = sys.modules.get("warp")
    if wp is not None:
        wp.config.quiet = False
        wp.config.log_level = wp.LOG_INFO


def configure_warp(wp) -> None:
    """Apply newton_lab's settings to the imported ``warp`` module: no adjoint kernels (unless
    ``NEWTON_LAB_WARP_BACKWARD=1``), and quiet (unless ``NEWTON_LAB_VERBOSE=1``)."""
    if not keep_backward():
        wp.config.enable_backward = False
    quiet_warp(wp)


class _ConfigureOnImport(importlib.abc.MetaPathFinder):
    """Finds ``warp`` once, through the normal path finder, and runs ``configure_warp`` right after Warp's
    ``__init__`` has executed (before Newton or any project code creates a kernel module)."""

    def find_spec(self, fullname, path, target=None):
        if fullname != "warp":
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        if spec is None or spec.loader is None:
            return spec
        loader_exec = spec.loader.exec_module

        def exec_module(module):
            loader_exec(module)
            configure_warp(module)

        spec.loader.exec_module = exec_module
        return spec


def install() -> None:
    """Configure Warp now if it is imported already, else as soon as it is (once per process)."""
    if "warp" in sys.modules:
        configure_warp(sys.modules["warp"])
    elif not any(isinstance(f, _ConfigureOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _ConfigureOnImport())
