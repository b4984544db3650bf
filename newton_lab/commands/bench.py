"""Arguments of the benchmarks: ``bench``, ``bench-collect``, ``bench-train``, ``bench-refusals``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from ..task_api.registry import DEFAULT_TASK_ID


@dataclass(kw_only=True)
class RunRecordArgs:
    """Where a benchmark writes its run record (``newton_lab.records``)."""

    run_record: str | None = None
    """write the run record (JSON: command, commit, date, device, figures) here (default
    outputs/records/<command>-<task>-<UTC time>.json)"""


@dataclass(kw_only=True)
class BenchEnvArgs(RunRecordArgs):
    """The env a benchmark times: task, rows and device."""

    task: str = DEFAULT_TASK_ID
    """task id (see `newton-lab tasks`)"""
    num_envs: int = 4
    """Parallel env rows."""
    device: str | None = None
    """Warp device, e.g. cpu or cuda:0 (default: Warp's)"""


@dataclass(kw_only=True)
class BenchArgs(BenchEnvArgs):
    """``newton-lab bench``: env-steps/s of the captured step vs the bare solver on the same model."""

    steps: int = 200
    """Env steps timed."""
    camera: str | None = None
    """also time the step with this G1 camera rendered every step (front_head, left_wrist, right_wrist)"""
    resolution: list[int] | None = None
    """camera image width and height [px] (default 128 128)"""
    camera_data: list[str] | None = None
    """camera outputs: rgb, depth, segmentation (default rgb)"""
    cameras: str | None = None
    """several views rendered every step instead of --camera, as collect's --cameras (e.g.
    front_head=96x72:rgb,left_wrist=96x72:rgb); the ceiling renders each of them bare"""
    render_orders: bool = False
    """with cameras: also time the step and its ceiling under each of the renderer's traversal orders, tile and
    thread-block sizes (the same pixels, other speeds; the env's own: newton_lab/envs/render_settings.py)"""


@dataclass(kw_only=True)
class BenchCollectArgs(BenchEnvArgs):
    """``newton-lab bench-collect``: expert collection throughput, seconds split into physics / agent / writer."""

    episodes: int = 16
    """Successful demos to collect (after a first-use run of one episode per row)."""
    dataset_path: str = "outputs/bench_collect.zarr"
    """Fresh dataset to write (.zarr or .hdf5); the first-use and prefilled runs write beside it."""
    prefill: int = 10_000
    """Episodes stored before the second run, which appends to that full dataset (0: skip it)."""
    workers: int = 1
    """Dask worker processes collecting at once (one per GPU with no --device or --device cuda), each into its own
    shard <stem>_w<i>; no prefilled run."""
    replan_batch: int | None = None
    """restarted rows the expert plans together (PlannerAgent.replan_batch); default: one per 16 env rows from 128
    rows on, else 1; 1 plans each restarted row at once"""
    replan_wait: int | None = None
    """most steps a restarted row holds before the expert plans it (PlannerAgent.replan_wait; default 12): with
    --replan-batch, how large the batches can grow"""
    trace: str | None = None
    """write a torch.profiler trace of 20 steps of the timed run to this path (.json.gz; Perfetto opens it): CPU
    ops, Python calls and, on a GPU, every kernel and copy (Warp's too); the costliest operations go to <path>.txt"""
    trace_after: int = 300
    """vector steps of the timed run before --trace records (past PickCube's first episode ends; they come in bursts)"""
    writer: Literal["auto", "thread", "process"] = "auto"
    """who writes the episodes (collect's --writer): a thread, or a process fed shared-memory blocks; auto: the
    process from 256 rows on"""
    baseline: bool = False
    """with --workers: also time worker 0 alone on one worker's share, before (<stem>_alone) and after (<stem>_alone2)
    the workers' run, and print the scaling, the workers' demos/s over the mean lone rate (same cluster, same demos
    per GPU)"""
    cameras: str = "none"
    """views rendered and recorded every step, as collect's --cameras: none (state only), default (the task's) or
    <camera>=<W>x<H>[:<data>+...][,...] (e.g. front_head=96x72:rgb,left_wrist=96x72:rgb)"""
    task_options: dict[str, Any] = field(default_factory=dict, metadata={"task_options": True})


@dataclass(kw_only=True)
class BenchTrainArgs(RunRecordArgs):
    """``newton-lab bench-train``: diffusion-policy training steps/s, eager vs CUDA-graph step."""

    dataset_path: str
    """Dataset the batches are drawn from."""
    batch_size: int = 1024
    """Windows per training step."""
    steps: int = 200
    """Training steps timed per variant."""
    preset: Literal["default", "cpu", "vision", "vision_cpu"] = "default"
    """Named training settings (network size)."""
    bf16: bool = False
    """also time the steps under bfloat16 autocast (float32 and bf16 side by side)"""
    channels_last: bool = False
    """also time each variant with the network's weights in channels-last layout (the image encoders' convolutions
    then run channels-last: keys ..._cl)"""
    cudnn_benchmark: bool = False
    """also time each variant with cuDNN's autotuner on (torch.backends.cudnn.benchmark: keys ..._tuned)"""
    compile: bool = False
    """also time the steps through torch.compile (the eager one, and on CUDA the captured one), at bf16 when --bf16
    and tuned when --cudnn-benchmark (keys ..._compiled...; compiling takes a minute or more)"""
    bf16_norms: bool = False
    """also time the captured step under bf16 with its GroupNorms in bf16 too (CUDA autocast otherwise runs them in
    float32; key CudaGraphTrainStep_bf16norms_bf16...)"""
    native_norms: bool = False
    """with --bf16-norms: also time that variant with PyTorch's own group-norm kernels (on CUDA the bf16 GroupNorms
    run through the layer-norm kernels: newton_lab/policies/norm.py; key ..._nativenorms_bf16norms...)"""
    profile: bool = False
    """also profile the eager step's operators (torch.profiler): device time per step by operator and by family
    (convolution, normalisation, matmul, cast and copy, optimiser, other), in the record's profile"""
    obs_keys: str | None = None
    """comma-separated obs terms to condition on, as train's (default: the preset's)"""
    image_keys: str | None = None
    """comma-separated camera terms the policy sees, as train's (e.g. front_head_rgb,left_wrist_rgb: the
    long-horizon recipe's two views; default: the preset's)"""
    device: str = "cpu"
    """Torch device (cpu, cuda, cuda:1, ...)."""

    def key_overrides(self) -> dict[str, tuple[str, ...]]:
        """``--obs-keys`` / ``--image-keys`` as the training config's tuples (only those given)."""
        return {
            key: tuple(k.strip() for k in getattr(self, key).split(",") if k.strip())
            for key in ("obs_keys", "image_keys")
            if getattr(self, key)
        }


@dataclass(kw_only=True)
class BenchRefusalsArgs(RunRecordArgs):
    """``newton-lab bench-refusals``: every case of the bad-input table in a fresh ``newton-lab`` process, timed."""

    only: list[str] | None = None
    """time only the cases of these commands (e.g. split view; default: every case)"""


@dataclass(kw_only=True)
class ResultsArgs:
    """``newton-lab results``: the results page's headline tables, generated from the committed run records."""

    records: str = "docs/results"
    """folder of run records (*.json, written by pipeline and the bench commands)"""
    page: str = "docs/benchmarks.md"
    """markdown page whose generated block is rewritten"""
    check: bool = False
    """only compare: exit 1 when the page does not match the records"""


@dataclass(kw_only=True)
class SuiteArgs:
    """``newton-lab suite``: every headline row of the results page, one product command each, one after another;
    each row's run record is copied into --records and the page regenerated."""

    recipe: Literal["gpu", "cpu"] = "gpu"
    """gpu: the learned-policy rows (PickCube demo, PickToShelf, SortToShelf per object, StackCube-Phased) and the
    benchmarks on cuda:0; cpu: the demo and the CPU env-step row"""
    out: str = "outputs/suite"
    """folder of the rows' outputs (one subfolder per row)"""
    records: str = "docs/results"
    """where each row's record is copied, as <row>-<device>.json"""
    page: str = "docs/benchmarks.md"
    """results page regenerated from --records at the end"""
    only: list[str] | None = None
    """run only these rows (names: --dry-run lists them)"""
    dry_run: bool = False
    """print each row's command and run nothing"""
