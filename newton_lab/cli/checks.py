"""Argument checks shared by the console script and the examples: each bad value is refused in one line, naming
the flag and the fix, before Warp, Newton or torch is imported and before any file is created."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from ..commands import (BenchArgs, BenchCollectArgs, BenchTrainArgs, CollectArgs, EvaluateArgs, ExportArgs, MimicArgs, PipelineArgs,
                        SplitArgs, TrainArgs, ViewArgs, camera_option)
from ..task_api.catalog import (check_task_id, check_task_options, declared_mimic_arms, declared_phases,
                                declared_sources, did_you_mean)
from ..task_api.cfg import IMAGE_DATA
from .file_checks import check_append, check_checkpoints, check_train

COUNT_FIELDS = ("num_envs", "episodes", "max_steps", "steps", "demos", "mimic_episodes", "eval_episodes", "workers",
                "batch_size", "rerun_worlds", "rerun_image_every", "max_attempts", "train_steps", "epochs",
                "checkpoint_every_steps", "eval_max_steps", "gpus")
"""Fields that count something: an integer >= 1 when given."""
DEVICE = re.compile(r"cpu|cuda(:\d+)?")
"""The devices a command takes: Warp's and torch's names for the CPU and a CUDA GPU."""
RUNNERS = ("local", "dask")
"""The pipeline's task runners."""
SEED_MAX = 2**30 - 1
"""Largest ``--seed``: Warp's reset kernels take 32-bit seeds, and the pipeline derives seed + 1 (Mimic) and
seed + 10000 (evaluation) from it; numpy takes no negative seed."""
ENV_BYTES = 512 << 10
"""Memory one env row takes, with a margin [bytes] (the model, state and solver data of one world with its contact
buffers: 160 KB measured on the CPU for Reach, 230 KB for PickToShelf). ``--num-envs`` beyond the machine's memory divided by
this is refused before any allocation (a 10,000,000-row request tried to allocate gigabytes for 25 s before)."""
ADDRESS = re.compile(r"(?:(?:tcp|tls|ucx|ws|wss)://)?(?:\[[0-9a-fA-F:]+\]|[\w.\-]+):\d{1,5}")
"""A Dask scheduler address: [protocol://]host:port."""
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
    if "seed" in names and (not isinstance(args.seed, int) or isinstance(args.seed, bool)
                            or not 0 <= args.seed <= SEED_MAX):
        raise ValueError(f"--seed must be an integer in [0, {SEED_MAX}] (Warp's kernels take 32-bit seeds), got "
                         f"{args.seed!r}")
    if "retries" in names and (not isinstance(args.retries, int) or isinstance(args.retries, bool)
                               or args.retries < 0):
        raise ValueError(f"--retries must be an integer >= 0 (0: no retry), got {args.retries!r}")
    if "num_envs" in names and args.num_envs is not None:
        check_num_envs(args.num_envs, device=getattr(args, "device", None))
    if "gpus" in names and args.gpus > 1:
        check_gpus(args.gpus, getattr(args, "device", None))
    if isinstance(args, PipelineArgs):
        check_pipeline(args)
    check_run_options(args, names)
    if "runner" in names and args.runner not in RUNNERS:
        raise ValueError(f"--runner {args.runner!r}{did_you_mean(args.runner, RUNNERS)}: use {' or '.join(RUNNERS)}")
    if "cameras" in names:
        check_cameras(camera_option(args.cameras))
    if isinstance(args, BenchArgs) and args.camera is not None:
        check_cameras({args.camera: {"resolution": tuple(args.resolution or (128, 128)),
                                     "data": tuple(args.camera_data or ("rgb",))}}, "--camera")
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
        check_checkpoints(args)
    if isinstance(args, SplitArgs):
        check_split_out(args)
    for name in EXISTING_FIELDS.get(type(args), ()):
        value = getattr(args, name)
        if value is not None and not Path(value).exists():
            raise FileNotFoundError(f"{_label(args, name)} {value} does not exist; check the path")
    if isinstance(args, ViewArgs) and not args.save and not args.spawn:
        raise ValueError("view needs --save file.rrd (headless) or --spawn (open a rerun viewer)")
    for cls, name in DATASET_INPUTS.items():
        if isinstance(args, cls):
            check_datasets(args, name)
    if isinstance(args, CollectArgs) and Path(args.dataset_path).exists():
        check_append(args)
    if isinstance(args, TrainArgs):
        check_train(args)


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
        if isinstance(args, SplitArgs) and args.out and info["task_id"] not in declared_phases():
            raise ValueError(f"{path} was recorded on {info['task_id']}, which has no phases; nothing to split (a "
                             "coherent task's dataset splits by phase: " + ", ".join(declared_phases()) + ")")
        if isinstance(args, MimicArgs):
            check_mimic_output(args, path, info)
        if isinstance(args, SplitArgs) and args.phases:
            check_split_phases(args, path, info)
        if isinstance(args, ViewArgs) and args.episode not in ids:
            listed = ", ".join(map(str, ids[:5])) + (", ..." if len(ids) > 5 else "")
            raise ValueError(f"--episode {args.episode}: {path} has no episode {args.episode}; its {len(ids)} "
                             f"episodes: {listed or 'none'}")


def check_mimic_output(args: MimicArgs, path: str, info: dict[str, Any]) -> None:
    """Mimic's source: its task has a Mimic variant and its actions command the arm the variant segments; an existing
    output dataset holds demos of the same task."""
    task_id = info["task_id"]
    variants = [v for v, source in declared_sources().items() if source == task_id]
    if not variants:
        raise ValueError(f"task {task_id!r} has no Mimic variant; tasks with one: "
                         f"{', '.join(sorted(set(declared_sources().values())))}")
    src = Path(path)
    out = Path(args.output_path) if args.output_path else src.with_name(f"{src.stem}_mimic{src.suffix}")
    from ..datasets import read_dataset_info  # deferred: the datasets package imports h5py and zarr (~1 s)
    from ..datasets.outputs import output_path  # deferred: as above

    output_path(out, create=False)  # a file on its path: refused now
    if out.exists():

        held = read_dataset_info(out)["task_id"]  # a one-line ValueError if it is no dataset or is damaged
        if held != task_id:  # Mimic's demos are recorded under their source's task id
            raise ValueError(f"{out} holds a dataset of task {held!r}, not {task_id!r}; choose another "
                             "--output-path")
    names = info["env_args"].get("newton_lab", {}).get("action_joint_names")
    arm = declared_mimic_arms().get(task_id, "left")
    if names is not None:
        from ..robots.registry import joint_group_facts  # deferred: numpy, only for mimic

        if not all(j in names for j in joint_group_facts().get(f"{arm}_arm", ())):
            raise ValueError(f"{path}: actions do not hold the {arm} arm joints; Mimic needs arm joint-target actions "
                             "(demos of the task's expert, newton-lab collect)")


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
        raise ValueError(f"--num-envs {num_envs:,} needs about {num_envs * ENV_BYTES / 2**30:,.0f} GiB "
                         f"({ENV_BYTES >> 10} KiB per row) and {where} {memory / 2**30:,.0f} GiB; use at most "
                         f"--num-envs {most:,}")


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
        out = subprocess.run([sys.executable, "-I", "-S", "-c", CUDA_MEMORY, str(index)], capture_output=True,
                             text=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired):
        return None
    answer = out.stdout.strip()
    return int(answer) if answer.isdigit() else None


def check_gpus(gpus: int, device: str | None) -> None:
    """``--gpus`` N > 1 asks for N data-parallel processes: one CUDA device each, or (``--device cpu``) one CPU core
    each for gloo; refuse more than the machine has."""
    devices = cuda_devices() if device is None or str(device).startswith("cuda") else 0
    if isinstance(devices, int) and devices > 0:
        if gpus > devices:
            raise ValueError(f"--gpus {gpus}: this machine has {devices} CUDA device{'s' * (devices > 1)}; use "
                             f"--gpus {devices} or fewer")
        return
    if device is not None and str(device).startswith("cuda"):
        return  # the device check said why there is none
    cores = os.cpu_count() or 1
    if gpus > cores:
        raise ValueError(f"--gpus {gpus}: with no CUDA device each is a gloo process on a CPU core, and this machine "
                         f"has {cores}; use --gpus {cores} or fewer")


def check_pipeline(args: PipelineArgs) -> None:
    """The pipeline's flags that no stage would refuse before Prefect starts."""
    mimicked = sorted(set(declared_sources().values()))
    if args.task not in declared_phases() and args.task not in mimicked:
        raise ValueError(f"{args.task} has no Mimic variant, and the pipeline runs collect -> mimic -> train -> "
                         f"evaluate; pipelines run on {', '.join(mimicked)} and the coherent tasks "
                         f"{', '.join(declared_phases())}")
    if args.mimic_episodes is not None and args.task in declared_phases():
        raise ValueError(f"{args.task} is a coherent task: its pipeline takes more coherent demos (--demos) instead "
                         "of Mimic; drop --mimic-episodes")
    if args.address is not None:
        if args.runner != "dask":
            raise ValueError(f"--address {args.address} names a Dask scheduler; add --runner dask, or drop "
                             "--address")
        if not ADDRESS.fullmatch(args.address):
            raise ValueError(f"--address {args.address!r} is not a scheduler address; write [tcp://]HOST:PORT, e.g. "
                             "tcp://10.0.0.5:8786")


def check_run_options(args: Any, names: set[str]) -> None:
    """Flags whose misuse a run found only after Warp loaded: a scenario saved from more than one row or episode, an
    --init-scenario that does not exist, a rerun recording not named .rrd, bench-collect's one-worker baseline."""
    if isinstance(args, CollectArgs) and args.save_end_scenario is not None:
        if args.num_envs != 1 or args.episodes != 1:
            raise ValueError(f"--save-end-scenario needs --num-envs 1 and --episodes 1, got {args.num_envs} and "
                             f"{args.episodes}")
        if Path(args.save_end_scenario).exists():
            raise FileExistsError(f"scenario file {args.save_end_scenario} already exists; choose a new path")
    scenario = (getattr(args, "task_options", None) or {}).get("init_scenario")
    if scenario is not None and not Path(scenario).is_file():
        raise FileNotFoundError(f"scenario file {scenario} does not exist; check the path (or save one with "
                                "--save-end-scenario)")
    if "rerun_save" in names and args.rerun_save is not None and Path(args.rerun_save).suffix.lower() != ".rrd":
        raise ValueError(f"--rerun-save {args.rerun_save}: a rerun recording is an .rrd file; name it e.g. run.rrd")
    if isinstance(args, BenchCollectArgs) and args.workers == 1 and args.baseline:
        raise ValueError("--baseline compares --workers W (W >= 2) with one worker alone; add --workers 2")
    if isinstance(args, PipelineArgs):
        from ..datasets.outputs import output_path  # deferred: the datasets package imports h5py and zarr (~1 s)

        output_path(Path(args.out) / ".prefect", create=False)  # --out (or a folder above it) a file: refused now


def check_cameras(cameras: Any, label: str = "--cameras") -> None:
    """Each camera of a ``make_env(cameras=...)`` dict is a mount of the robot, at a resolution in its range, with
    data it renders (once each)."""
    if not isinstance(cameras, dict):
        return
    from ..robots.registry import camera_facts  # deferred: numpy, only when cameras are named

    mounts, lo, hi = camera_facts()
    for name, spec in cameras.items():
        if name not in mounts:
            raise ValueError(f"{label}: unknown camera {name!r}{did_you_mean(name, mounts)}; the G1's cameras are "
                             f"{', '.join(mounts)}")
        res = spec if isinstance(spec, tuple) else spec.get("resolution", ())
        if len(res) != 2 or not all(lo <= v <= hi for v in res):
            raise ValueError(f"{label}: camera {name!r} resolution {'x'.join(map(str, res))} is out of range; width "
                             f"and height are in [{lo}, {hi}] px, e.g. {name}=96x72")
        data = () if isinstance(spec, tuple) else tuple(spec.get("data", ()))
        for d in data:
            if d not in IMAGE_DATA:
                raise ValueError(f"{label}: camera {name!r} data {d!r}{did_you_mean(d, IMAGE_DATA)} is unknown; use "
                                 f"{', '.join(IMAGE_DATA)}, joined with +")
        if len(set(data)) != len(data):
            raise ValueError(f"{label}: camera {name!r} names data {'+'.join(data)} with a repeat; name each once")


def check_split_out(args: SplitArgs) -> None:
    """``split --out`` is a new folder (or an empty one), and ``--phases`` names at least one phase."""
    if args.phases is not None and not args.phase_names():
        raise ValueError(f"--phases {args.phases!r} names no phase; give comma-separated names, e.g. --phases "
                         "pick,place")
    if args.out is None:
        return
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"--out {out} is a file; split into a new folder")
    if out.is_dir() and any(out.iterdir()):
        raise FileExistsError(f"--out {out} is a folder that holds files already; split into a new folder")
