"""Checks of the devices and memory a command asks for (``--device``, ``--num-envs``, ``--gpus``), answered before
Warp, Newton or torch is imported: the CUDA driver is asked in a child process, so that this one never initialises
CUDA (a process that forks workers later could not use it in them)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

DEVICE = re.compile(r"cpu|cuda(:\d+)?")
"""The devices a command takes: Warp's and torch's names for the CPU and a CUDA GPU."""
ENV_BYTES = 512 << 10
"""Memory one env row takes, with a margin [bytes] (the model, state and solver data of one world with its contact
buffers: 160 KB measured on the CPU for Reach, 230 KB for PickToShelf). ``--num-envs`` beyond the machine's memory
divided by this is refused before any allocation (a 10,000,000-row request tried to allocate gigabytes for 25 s
before)."""
CUDA_COUNT = """
import ctypes
try:
    cuda = ctypes.CDLL("libcuda.so.1")
except OSError:
    print("no NVIDIA driver: libcuda.so.1 not found"); raise SystemExit
n, err = ctypes.c_int(0), cuda.cuInit(0)
err = err or cuda.cuDeviceGetCount(ctypes.byref(n))
print(n.value if not err else f"the driver answers cuInit with CUDA error {err}")
"""
"""Prints how many CUDA devices the driver shows (after CUDA_VISIBLE_DEVICES), or why there are none."""


def cuda_devices() -> int | str:
    """How many CUDA devices this process would see, or why it sees none. Asked of the driver in a child process:
    this one must not initialise CUDA (a process that forks workers later could not use it in them)."""
    if not sys.platform.startswith("linux"):
        return 1 << 30  # not checked here: Warp says
    out = subprocess.run([sys.executable, "-I", "-S", "-c", CUDA_COUNT], capture_output=True, text=True, timeout=120)
    answer = out.stdout.strip() or f"the device check failed ({out.stderr.strip().splitlines()[-1:]})"
    return int(answer) if answer.isdigit() else answer


def check_cuda_device(label: str, device: str, devices: int | str) -> None:
    """Refuse ``cuda`` / ``cuda:N`` when the machine has no such device (``devices``: a count, or why none)."""
    index = int(device.partition(":")[2] or 0)
    if isinstance(devices, str) or devices == 0:
        why = devices if isinstance(devices, str) else "the driver shows no device"
        raise ValueError(f"{label} {device}: no CUDA device here ({why}); use {label} cpu")
    if index >= devices:
        raise ValueError(
            f"{label} {device}: this machine has {devices} CUDA device{'s' * (devices > 1)} "
            f"(cuda:0{f' to cuda:{devices - 1}' if devices > 1 else ''}); use one of them or cpu"
        )


def _memory_bytes() -> int | None:
    """This machine's physical memory [bytes], or None where the system does not say."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_num_envs(num_envs: int, memory: int | None = None, device: str | None = None) -> None:
    """Refuse more env rows than the memory that holds them takes (``ENV_BYTES`` each), before anything is allocated:
    the GPU's for ``cuda[:N]`` (asked of the driver in a child process, only for a request of more than 1 GiB), else
    this machine's."""
    where = "this machine has"
    if memory is None and device is not None and str(device).startswith("cuda") and num_envs * ENV_BYTES > 1 << 30:
        memory = cuda_memory(int(str(device).partition(":")[2] or 0))
        where = f"{device} has" if memory else where
    memory = _memory_bytes() if memory is None else memory
    if memory and num_envs * ENV_BYTES > memory:
        most = memory // ENV_BYTES
        raise ValueError(
            f"--num-envs {num_envs:,} needs about {num_envs * ENV_BYTES / 2**30:,.0f} GiB "
            f"({ENV_BYTES >> 10} KiB per row) and {where} {memory / 2**30:,.0f} GiB; use at most "
            f"--num-envs {most:,}"
        )


CUDA_MEMORY = """
import ctypes, sys
cuda = ctypes.CDLL("libcuda.so.1")
dev, total = ctypes.c_int(0), ctypes.c_size_t(0)
err = cuda.cuInit(0) or cuda.cuDeviceGet(ctypes.byref(dev), int(sys.argv[1]))
err = err or cuda.cuDeviceTotalMem_v2(ctypes.byref(total), dev)
print(total.value if not err else "")
"""
"""Prints the total memory of CUDA device argv[1] [bytes], or nothing."""


def cuda_memory(index: int) -> int | None:
    """Total memory of CUDA device ``index`` [bytes] from the driver, in a child process; None when it does not say
    (the device check has refused a missing device already)."""
    try:
        out = subprocess.run(
            [sys.executable, "-I", "-S", "-c", CUDA_MEMORY, str(index)], capture_output=True, text=True, timeout=120
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    answer = out.stdout.strip()
    return int(answer) if answer.isdigit() else None


STEP_BYTES = 1 << 10
"""Memory one recorded step of one row takes while its episode runs [bytes]: collect's recorder holds
``--max-steps`` steps per row (observations, actions and states: 186 float32 columns for PickCube, so 1 KiB leaves a
margin). A ``--max-steps`` of 10**17 made it ask torch for an overflowing allocation after Warp loaded."""


def check_recorded_steps(num_envs: int, max_steps: int, memory: int | None = None) -> None:
    """Refuse a ``--max-steps`` whose recorder (``num_envs`` rows of ``max_steps`` steps, ``STEP_BYTES`` each) the
    machine's memory cannot hold."""
    memory = _memory_bytes() if memory is None else memory
    if memory and num_envs * max_steps * STEP_BYTES > memory:
        most = memory // (num_envs * STEP_BYTES)
        raise ValueError(
            f"--max-steps {max_steps:,} with --num-envs {num_envs:,} records about "
            f"{num_envs * max_steps * STEP_BYTES / 2**30:,.0f} GiB per episode ({STEP_BYTES >> 10} KiB "
            f"per step and row) and this machine has {memory / 2**30:,.0f} GiB; use at most "
            f"--max-steps {most:,}"
        )


def check_workers(workers: int, device: str | None) -> None:
    """A local Dask cluster's ``--workers``: one process per GPU (at most as many as the GPUs: more are not started),
    or with no CUDA device one per CPU core; refuse more processes than cores."""
    devices = cuda_devices() if device is None or str(device).startswith("cuda") else 0
    if (isinstance(devices, int) and devices > 0) or workers == 1:
        return
    cores = os.cpu_count() or 1
    if workers > cores:
        raise ValueError(
            f"--workers {workers}: with no CUDA device a local Dask cluster runs a worker process per CPU "
            f"core, and this machine has {cores}; use --workers {cores} or fewer, or --address of a "
            "cluster"
        )


def check_gpus(gpus: int, device: str | None) -> None:
    """``--gpus`` N > 1 asks for N data-parallel processes: one CUDA device each, or (``--device cpu``) one CPU core
    each for gloo; refuse more than the machine has."""
    devices = cuda_devices() if device is None or str(device).startswith("cuda") else 0
    if isinstance(devices, int) and devices > 0:
        if gpus > devices:
            raise ValueError(
                f"--gpus {gpus}: this machine has {devices} CUDA device{'s' * (devices > 1)}; use "
                f"--gpus {devices} or fewer"
            )
        return
    if device is not None and str(device).startswith("cuda"):
        return  # the device check said why there is none
    cores = os.cpu_count() or 1
    if gpus > cores:
        raise ValueError(
            f"--gpus {gpus}: with no CUDA device each is a gloo process on a CPU core, and this machine "
            f"has {cores}; use --gpus {cores} or fewer"
        )
