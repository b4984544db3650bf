"""Argument checks shared by the console script and the examples: each bad value is refused in one line, naming
the flag and the fix, before Warp, Newton or torch is imported and before any file is created."""

from __future__ import annotations

import importlib.util
import re
import tempfile
from pathlib import Path
from typing import Any

from ..task_api.catalog import check_task_id, check_task_options, declared_phases, declared_sources, did_you_mean
from ..task_api.cfg import IMAGE_DATA
from .bench import BenchArgs, BenchCollectArgs, BenchTrainArgs
from .device_checks import (
    DEVICE,
    check_cuda_device,
    check_gpus,
    check_num_envs,
    check_recorded_steps,
    check_workers,
    cuda_devices,
)
from .env import RenderArgs, camera_option
from .file_checks import check_append, check_checkpoints, check_datasets, check_split_out, check_train, flag_of
from .perception import (
    YoloExportArgs,
    YoloPredictArgs,
    YoloTrainArgs,
    check_resolution,
    check_yolo_export,
    check_yolo_predict,
    check_yolo_train,
)
from .pipeline import PipelineArgs
from .rl import TrainRLArgs
from .teleop import TeleopArgs, check_teleop
from .workflow import CollectArgs, EvaluateArgs, ExportArgs, MimicArgs, SplitArgs, TrainArgs, ViewArgs

COUNT_FIELDS = (
    "num_envs",
    "episodes",
    "max_steps",
    "steps",
    "demos",
    "mimic_episodes",
    "eval_episodes",
    "workers",
    "batch_size",
    "rerun_worlds",
    "rerun_image_every",
    "max_attempts",
    "train_steps",
    "epochs",
    "mini_batches",
    "checkpoint_every_steps",
    "eval_max_steps",
    "gpus",
)
"""Fields that count something: an integer >= 1 when given."""
RUNNERS = ("local", "dask")
"""The pipeline's task runners."""
SEED_MAX = 2**30 - 1
"""Largest ``--seed``: Warp's reset kernels take 32-bit seeds, and the pipeline derives seed + 1 (Mimic) and
seed + 10000 (evaluation) from it; numpy takes no negative seed."""
ADDRESS = re.compile(r"(?:(?:tcp|tls|ucx|ws|wss)://)?(?:\[[0-9a-fA-F:]+\]|[\w.\-]+):\d{1,5}")
"""A Dask scheduler address: [protocol://]host:port."""
DATASET_FIELDS = ("dataset_path", "output_path")
"""Fields naming a dataset file: its suffix picks the format."""
EXISTING_FIELDS = {
    MimicArgs: ("dataset_path",),
    EvaluateArgs: ("checkpoint",),
    ViewArgs: ("dataset",),
    BenchTrainArgs: ("dataset_path",),
}
"""Fields naming an input that must exist, per command."""
DATASET_INPUTS = {
    MimicArgs: "dataset_path",
    ViewArgs: "dataset",
    BenchTrainArgs: "dataset_path",
    ExportArgs: "dataset_path",
    SplitArgs: "dataset_path",
    TrainArgs: "dataset_path",
}
"""The field naming the dataset(s) a command reads: each must open as a newton_lab dataset."""


def check_args(args: Any) -> None:
    """Refuse bad arguments in one line before anything is imported, built or written (``ValueError`` /
    ``FileNotFoundError`` naming the field and the fix)."""
    names = {f for f in getattr(args, "__dataclass_fields__", {})}
    if "task" in names and args.task is not None:  # (an example's optional --task)
        check_task_id(args.task)  # first: it needs no import at all (typo'd ids answer at once)
        check_task_options(args.task, getattr(args, "task_options", None) or {})
    _check_scalars(args, names)
    if "num_envs" in names and args.num_envs is not None:
        check_num_envs(args.num_envs, device=getattr(args, "device", None))
        if "max_steps" in names and args.max_steps is not None and isinstance(args, CollectArgs):
            check_recorded_steps(args.num_envs, args.max_steps)
    if "gpus" in names and args.gpus > 1:
        check_gpus(args.gpus, getattr(args, "device", None))
    if isinstance(args, PipelineArgs):
        check_pipeline(args)
    check_run_options(args, names)
    if "runner" in names and args.runner not in RUNNERS:
        raise ValueError(f"--runner {args.runner!r}{did_you_mean(args.runner, RUNNERS)}: use {' or '.join(RUNNERS)}")
    if "cameras" in names:
        check_cameras(camera_option(args.cameras))
    if isinstance(args, BenchArgs) and args.camera is not None and args.cameras is not None:
        raise ValueError("--camera and --cameras both given; give one (--cameras takes several views)")
    if isinstance(args, BenchTrainArgs) and args.native_norms and not (args.bf16 and args.bf16_norms):
        raise ValueError("--native-norms times the bf16 norms on PyTorch's kernels; add --bf16 --bf16-norms")
    if isinstance(args, BenchArgs) and args.render_orders and args.camera is None and args.cameras is None:
        raise ValueError("--render-orders times the camera render; add --cameras (e.g. front_head=96x72:rgb)")
    if isinstance(args, BenchArgs) and args.cameras is not None and not camera_option(args.cameras):
        raise ValueError(f"--cameras {args.cameras!r} names no view to time; name one or more (front_head=96x72:rgb)")
    if isinstance(args, BenchArgs) and args.camera is not None:
        check_cameras(
            {
                args.camera: {
                    "resolution": tuple(args.resolution or (128, 128)),
                    "data": tuple(args.camera_data or ("rgb",)),
                }
            },
            "--camera",
        )
    for name in names & {"checkpoint_every_s", "time_budget_s", "episode_length_s"}:
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise ValueError(f"{flag_of(args, name)} must be > 0 [s], got {value!r}")
    _check_dataset_suffixes(args, names)
    if isinstance(args, EvaluateArgs):
        check_checkpoints(args)
        args.perturbation_cells()
    if isinstance(args, CollectArgs):
        args.domain_randomization()
    if isinstance(args, (CollectArgs, PipelineArgs)) and not 0 <= args.distractors <= 3:
        raise ValueError(f"--distractors {args.distractors}: there are 0 to 3 distractor objects; give 0, 1, 2 or 3")
    if isinstance(args, SplitArgs):
        check_split_out(args)
    for name in EXISTING_FIELDS.get(type(args), ()):
        value = getattr(args, name)
        if value is not None and not Path(value).exists():
            raise FileNotFoundError(f"{flag_of(args, name)} {value} does not exist; check the path")
    if isinstance(args, ViewArgs) and not args.save and not args.spawn:
        raise ValueError("view needs --save file.rrd (headless) or --spawn (open a rerun viewer)")
    for cls, name in DATASET_INPUTS.items():
        if isinstance(args, cls):
            check_datasets(args, name)
    if isinstance(args, CollectArgs) and Path(args.dataset_path).exists():
        check_append(args)
    if isinstance(args, TrainArgs):
        check_train(args)
    for cls, check in COMMAND_CHECKS.items():
        if isinstance(args, cls):
            check(args)


def _check_scalars(args: Any, names: set[str]) -> None:
    """Counts >= 1, ``--prefill`` >= 0, the simulation / training device, the seed's range and ``--retries`` >= 0."""
    for name in names & set(COUNT_FIELDS):
        value = getattr(args, name)
        if value is not None and (not isinstance(value, int) or isinstance(value, bool) or value < 1):
            raise ValueError(f"{flag_of(args, name)} must be an integer >= 1, got {value!r}")
    if "prefill" in names and (not isinstance(args.prefill, int) or isinstance(args.prefill, bool) or args.prefill < 0):
        raise ValueError(f"--prefill must be an integer >= 0, got {args.prefill!r}")
    # the simulation / training device (teleop's own --device names the operator's device; its --sim-device is this)
    sim = "sim_device" if "sim_device" in names else "device" if "device" in names else None
    value = getattr(args, sim) if sim else None
    if value is not None and not DEVICE.fullmatch(str(value)):
        raise ValueError(f"{flag_of(args, sim)} {value!r} is not a device; use cpu, cuda or cuda:N (e.g. cuda:0)")
    if value is not None and str(value).startswith("cuda"):
        check_cuda_device(flag_of(args, sim), str(value), cuda_devices())
    if "seed" in names and (
        not isinstance(args.seed, int) or isinstance(args.seed, bool) or not 0 <= args.seed <= SEED_MAX
    ):
        raise ValueError(
            f"--seed must be an integer in [0, {SEED_MAX}] (Warp's kernels take 32-bit seeds), got {args.seed!r}"
        )
    if "retries" in names and (not isinstance(args.retries, int) or isinstance(args.retries, bool) or args.retries < 0):
        raise ValueError(f"--retries must be an integer >= 0 (0: no retry), got {args.retries!r}")


def _check_dataset_suffixes(args: Any, names: set[str]) -> None:
    """Every dataset path argument names a known format by its suffix."""
    from ..datasets.storage import SUFFIXES  # deferred: the datasets package imports h5py and zarr (~1 s)

    for name in names & set(DATASET_FIELDS):
        value = getattr(args, name)
        paths = value if isinstance(value, list) else [value]
        for path in (p for p in paths if p is not None):
            if Path(path).suffix.lower() not in SUFFIXES:
                raise ValueError(
                    f"{flag_of(args, name)} {path}: unknown dataset suffix; use one of {', '.join(SUFFIXES)}"
                )


def check_writable(path: Path) -> None:
    """The folder of output ``path`` takes a new file (tried with an unnamed temporary file: nothing is left)."""
    try:
        with tempfile.TemporaryFile(dir=path.parent):
            pass
    except OSError as exc:  # permission denied, a read-only file system, a folder that takes no files (/proc)
        from ..datasets.files.output_paths import OutputPathError  # deferred: as above

        raise OutputPathError(
            f"cannot write {path}: {path.parent} takes no new file ({exc.strerror}); choose a writable path"
        ) from None


def check_pipeline(args: PipelineArgs) -> None:
    """The pipeline's flags that no stage would refuse before Prefect starts."""
    mimicked = sorted(set(declared_sources().values()))
    if args.task not in declared_phases() and args.task not in mimicked:
        raise ValueError(
            f"{args.task} has no Mimic variant, and the pipeline runs collect -> mimic -> train -> "
            f"evaluate; pipelines run on {', '.join(mimicked)} and the coherent tasks "
            f"{', '.join(declared_phases())}"
        )
    if args.mimic_episodes is not None and args.task in declared_phases():
        raise ValueError(
            f"{args.task} is a coherent task: its pipeline takes more coherent demos (--demos) instead "
            "of Mimic; drop --mimic-episodes"
        )
    if args.record and not args.dry_run and importlib.util.find_spec("rerun") is None:
        raise ValueError(
            "--record writes the evaluation's first episodes to <out>/evaluation.rrd with rerun, and rerun-sdk is "
            "not installed here; install the project's pins (pip install -e .), or pass --no-record"
        )
    if args.workers > 1 and args.runner != "dask":
        raise ValueError(
            f"--workers {args.workers} shards the stages over Dask workers, and the local runner runs "
            "them in this process; add --runner dask, or drop --workers"
        )
    if args.runner == "dask" and args.address is None:  # a local cluster: worker processes on this machine
        check_workers(args.workers, args.device)
    if args.address is not None:
        if args.runner != "dask":
            raise ValueError(f"--address {args.address} names a Dask scheduler; add --runner dask, or drop --address")
        if not ADDRESS.fullmatch(args.address):
            raise ValueError(
                f"--address {args.address!r} is not a scheduler address; write [tcp://]HOST:PORT, e.g. "
                "tcp://10.0.0.5:8786"
            )


def check_run_options(args: Any, names: set[str]) -> None:
    """Flags whose misuse a run found only after Warp loaded: a scenario saved from more than one row or episode, an
    --init-scenario that does not exist, a rerun recording not named .rrd, bench-collect's one-worker baseline."""
    if isinstance(args, CollectArgs) and args.save_end_scenario is not None:
        if args.num_envs != 1 or args.episodes != 1:
            raise ValueError(
                f"--save-end-scenario needs --num-envs 1 and --episodes 1, got {args.num_envs} and {args.episodes}"
            )
        if Path(args.save_end_scenario).exists():
            raise FileExistsError(f"scenario file {args.save_end_scenario} already exists; choose a new path")
    scenario = (getattr(args, "task_options", None) or {}).get("init_scenario")
    if scenario is not None and not Path(scenario).is_file():
        raise FileNotFoundError(
            f"scenario file {scenario} does not exist; check the path (or save one with --save-end-scenario)"
        )
    if "rerun_save" in names and args.rerun_save is not None and Path(args.rerun_save).suffix.lower() != ".rrd":
        raise ValueError(f"--rerun-save {args.rerun_save}: a rerun recording is an .rrd file; name it e.g. run.rrd")
    if isinstance(args, BenchCollectArgs) and args.workers == 1 and args.baseline:
        raise ValueError("--baseline compares --workers W (W >= 2) with one worker alone; add --workers 2")
    if (
        isinstance(args, BenchCollectArgs)
        and args.workers > 1
        and (args.replan_batch, args.replan_wait, args.trace) != (None, None, None)
    ):
        raise ValueError("--replan-batch, --replan-wait and --trace are for one process (--workers 1)")
    if isinstance(args, PipelineArgs):
        from ..datasets.files.output_paths import output_path  # deferred: datasets imports h5py and zarr (~1 s)

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
            raise ValueError(
                f"{label}: unknown camera {name!r}{did_you_mean(name, mounts)}; the G1's cameras are "
                f"{', '.join(mounts)}"
            )
        res = spec if isinstance(spec, tuple) else spec.get("resolution", ())
        if len(res) != 2 or not all(lo <= v <= hi for v in res):
            raise ValueError(
                f"{label}: camera {name!r} resolution {'x'.join(map(str, res))} is out of range; width "
                f"and height are in [{lo}, {hi}] px, e.g. {name}=96x72"
            )
        data = () if isinstance(spec, tuple) else tuple(spec.get("data", ()))
        for d in data:
            if d not in IMAGE_DATA:
                raise ValueError(
                    f"{label}: camera {name!r} data {d!r}{did_you_mean(d, IMAGE_DATA)} is unknown; use "
                    f"{', '.join(IMAGE_DATA)}, joined with +"
                )
        if len(set(data)) != len(data):
            raise ValueError(f"{label}: camera {name!r} names data {'+'.join(data)} with a repeat; name each once")


def check_render(args: RenderArgs) -> None:
    """``render``: a camera of the robot, its resolution, the expert's steps, the env's perturbations and a PNG to
    write."""
    from ..robots.registry import camera_facts  # deferred: numpy, only for this command

    mounts, _, _ = camera_facts()
    if args.camera not in mounts:
        raise ValueError(f"--camera {args.camera!r} is unknown; the G1's cameras are {', '.join(mounts)}")
    check_resolution(args.resolution)
    if args.expert_steps < 0:
        raise ValueError(f"--expert-steps must be >= 0, got {args.expert_steps}")
    if Path(args.out).suffix.lower() != ".png":
        raise ValueError(f"--out {args.out}: the picture is a PNG; name it e.g. render.png")
    args.perturbation()


def check_train_rl(args: TrainRLArgs) -> None:
    """``train-rl``'s output folder: a resume point to resume from, or no finished run in it; its domain
    randomisation."""
    args.domain_randomization()
    if not args.init_noise_std > 0:
        raise ValueError(f"--init-noise-std must be > 0 (action units), got {args.init_noise_std}")
    out_dir = Path(args.output_dir)
    if args.resume and not (out_dir / "resume.pt").is_file():
        raise FileNotFoundError(f"nothing to resume in {out_dir} (no resume.pt); start the run without --resume")
    if not args.resume and (out_dir / "checkpoint.pt").exists():
        raise FileExistsError(
            f"{out_dir} holds a finished run; choose a new --output-dir (or --resume an interrupted one)"
        )


COMMAND_CHECKS = {
    RenderArgs: check_render,
    TrainRLArgs: check_train_rl,
    TeleopArgs: check_teleop,
    YoloExportArgs: check_yolo_export,
    YoloTrainArgs: check_yolo_train,
    YoloPredictArgs: check_yolo_predict,
}
"""A command's own checks, after the shared ones."""
