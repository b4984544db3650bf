"""Argument checks shared by the console script and the examples: each bad value is refused in one line, naming
the flag and the fix, before Warp, Newton or torch is imported and before any file is created."""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from ..commands import (BenchTrainArgs, EvaluateArgs, ExportArgs, MimicArgs, SplitArgs, TrainArgs, ViewArgs,
                        camera_option)
from ..task_api.catalog import check_task_id, check_task_options, did_you_mean

COUNT_FIELDS = ("num_envs", "episodes", "max_steps", "steps", "demos", "mimic_episodes", "eval_episodes", "workers",
                "batch_size", "rerun_worlds", "rerun_image_every", "max_attempts", "train_steps", "epochs",
                "checkpoint_every_steps")
"""Fields that count something: an integer >= 1 when given."""
DEVICE = re.compile(r"cpu|cuda(:\d+)?")
"""The devices a command takes: Warp's and torch's names for the CPU and a CUDA GPU."""
RUNNERS = ("local", "dask")
"""The pipeline's task runners."""
DATASET_FIELDS = ("dataset_path", "output_path")
"""Fields naming a dataset file: its suffix picks the format."""
EXISTING_FIELDS = {MimicArgs: ("dataset_path",), EvaluateArgs: ("checkpoint",), ViewArgs: ("dataset",),
                   BenchTrainArgs: ("dataset_path",)}
"""Fields naming an input that must exist, per command."""
DATASET_INPUTS = {MimicArgs: "dataset_path", ViewArgs: "dataset", BenchTrainArgs: "dataset_path",
                  ExportArgs: "dataset_path", SplitArgs: "dataset_path", TrainArgs: "dataset_path"}
"""The field naming the dataset(s) a command reads: each must open as a newton_lab dataset."""
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


def _label(args: Any, name: str) -> str:
    """How the command line spells field ``name``: ``--flag-name``, or the bare name of a positional."""
    if args.__dataclass_fields__[name].metadata.get("positional"):
        return name
    return f"--{name.replace('_', '-')}"


def check_args(args: Any) -> None:
    """Refuse bad arguments in one line before anything is imported, built or written (``ValueError`` /
    ``FileNotFoundError`` naming the field and the fix)."""
    names = {f for f in getattr(args, "__dataclass_fields__", {})}
    if "task" in names and args.task is not None:  # (an example's optional --task)
        check_task_id(args.task)  # first: it needs no import at all (typo'd ids answer at once)
        check_task_options(args.task, getattr(args, "task_options", None) or {})
    for name in names & set(COUNT_FIELDS):
        value = getattr(args, name)
        if value is not None and (not isinstance(value, int) or isinstance(value, bool) or value < 1):
            raise ValueError(f"{_label(args, name)} must be an integer >= 1, got {value!r}")
    if "prefill" in names and (not isinstance(args.prefill, int) or isinstance(args.prefill, bool) or args.prefill < 0):
        raise ValueError(f"--prefill must be an integer >= 0, got {args.prefill!r}")
    # the simulation / training device (teleop's own --device names the operator's device; its --sim-device is this)
    sim = "sim_device" if "sim_device" in names else "device" if "device" in names else None
    value = getattr(args, sim) if sim else None
    if value is not None and not DEVICE.fullmatch(str(value)):
        raise ValueError(f"{_label(args, sim)} {value!r} is not a device; use cpu, cuda or cuda:N (e.g. cuda:0)")
    if value is not None and str(value).startswith("cuda"):
        check_cuda_device(_label(args, sim), str(value), cuda_devices())
    if "runner" in names and args.runner not in RUNNERS:
        raise ValueError(f"--runner {args.runner!r}{did_you_mean(args.runner, RUNNERS)}: use {' or '.join(RUNNERS)}")
    if "cameras" in names:
        camera_option(args.cameras)
    for name in names & {"checkpoint_every_s", "time_budget_s"}:
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise ValueError(f"{_label(args, name)} must be > 0 [s], got {value!r}")
    from ..datasets.storage import SUFFIXES  # deferred: the datasets package imports h5py and zarr (~1 s)

    for name in names & set(DATASET_FIELDS):
        value = getattr(args, name)
        paths = value if isinstance(value, list) else [value]
        for path in (p for p in paths if p is not None):
            if Path(path).suffix.lower() not in SUFFIXES:
                raise ValueError(f"{_label(args, name)} {path}: unknown dataset suffix; use one of "
                                 f"{', '.join(SUFFIXES)}")
    if isinstance(args, EvaluateArgs):
        phases = args.phase_checkpoints()
        if phases and args.checkpoint:
            raise ValueError("give --checkpoint (one policy for the whole task) or --phase-checkpoint (one per phase "
                             "of a coherent task), not both")
        for phase, path in phases.items():
            if not Path(path).exists():
                raise FileNotFoundError(f"--phase-checkpoint {phase}={path}: {path} does not exist; check the path")
    for name in EXISTING_FIELDS.get(type(args), ()):
        value = getattr(args, name)
        if value is not None and not Path(value).exists():
            raise FileNotFoundError(f"{_label(args, name)} {value} does not exist; check the path")
    if isinstance(args, ViewArgs) and not args.save and not args.spawn:
        raise ValueError("view needs --save file.rrd (headless) or --spawn (open a rerun viewer)")
    for cls, name in DATASET_INPUTS.items():
        if isinstance(args, cls):
            check_datasets(args, name)


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
        raise ValueError(f"{label} {device}: this machine has {devices} CUDA device{'s' * (devices > 1)} "
                         f"(cuda:0{f' to cuda:{devices - 1}' if devices > 1 else ''}); use one of them or cpu")


def check_datasets(args: Any, name: str) -> None:
    """The dataset(s) a command reads exist and open (and ``view``'s episode is in its dataset): one line each."""
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr (~1 s)

    value = getattr(args, name)
    for path in value if isinstance(value, list) else [value]:
        if not Path(path).exists():
            raise FileNotFoundError(f"{_label(args, name)} {path} does not exist; check the path")
        info = read_dataset_info(path)  # a one-line ValueError if it is no dataset or is damaged
        ids = info["demo_ids"]
        if isinstance(args, SplitArgs) and args.phases:
            check_split_phases(args, path, info)
        if isinstance(args, ViewArgs) and args.episode not in ids:
            listed = ", ".join(map(str, ids[:5])) + (", ..." if len(ids) > 5 else "")
            raise ValueError(f"--episode {args.episode}: {path} has no episode {args.episode}; its {len(ids)} "
                             f"episodes: {listed or 'none'}")


def check_split_phases(args: SplitArgs, path: str, info: dict[str, Any]) -> None:
    """``split --phases`` names phases that the dataset's task has (as recorded in its ``env_args``; a dataset
    recorded before the phase names were is checked after the task is built), and only with ``--out``."""
    if not args.out:
        raise ValueError("--phases selects the phases of a split by phase: give --out too")
    from ..datasets.split import check_phase_names  # deferred: the datasets package imports h5py and zarr (~1 s)

    recorded = info["env_args"].get("newton_lab", {}).get("phases")
    if recorded is not None:
        check_phase_names(path, info["task_id"], recorded, args.phase_names())


def check_writable(path: Path) -> None:
    """The folder of output ``path`` takes a new file (tried with an unnamed temporary file: nothing is left)."""
    try:
        with tempfile.TemporaryFile(dir=path.parent):
            pass
    except OSError as exc:  # permission denied, a read-only file system, a folder that takes no files (/proc)
        from ..datasets.outputs import OutputPathError  # deferred: as above

        raise OutputPathError(f"cannot write {path}: {path.parent} takes no new file ({exc.strerror}); "
                              "choose a writable path") from None
