"""``newton-lab bench``, ``bench-collect``, ``bench-train`` and ``bench-refusals``: measurements, each written as
a run record (arguments: ``newton_lab.commands.bench``)."""

from __future__ import annotations

import json
import sys

from ..commands import BenchArgs, BenchCollectArgs, BenchRefusalsArgs, BenchTrainArgs, camera_option
from ..records import write_run_record
from . import watchdog


def bench(args: BenchArgs) -> int:
    from ..bench import bench as measure  # deferred: Warp/Newton are slow to import

    if args.cameras is not None:
        cam = {"cameras": camera_option(args.cameras)}
    elif args.camera is not None:
        cam = {
            "camera": args.camera,
            "resolution": tuple(args.resolution or (128, 128)),
            "camera_data": tuple(args.camera_data or ("rgb",)),
        }
    else:
        cam = {}
    out = measure(
        args.task, num_envs=args.num_envs, steps=args.steps, device=args.device, render_orders=args.render_orders, **cam
    )
    write_run_record("bench", args.run_record, task=args.task, device=args.device, results=out)
    print(json.dumps(out))
    return 0


def bench_collect(args: BenchCollectArgs) -> int:
    from ..bench_collect import bench_collect, bench_collect_on_workers, summary  # deferred: Warp is slow to import

    common = {
        "num_envs": args.num_envs,
        "episodes": args.episodes,
        "device": args.device,
        "dataset_path": args.dataset_path,
        "writer": args.writer,
        "cameras": camera_option(args.cameras),
        "task_options": dict(args.task_options),
    }
    if args.workers == 1:
        out = bench_collect(
            args.task,
            prefill=args.prefill,
            replan_batch=args.replan_batch,
            replan_wait=args.replan_wait,
            trace=args.trace,
            trace_after=args.trace_after,
            **common,
        )
        print(summary(out), file=sys.stderr, flush=True)
    else:
        watchdog.start()  # killed, it leaves no Dask worker running
        out = bench_collect_on_workers(args.task, workers=args.workers, baseline=args.baseline, **common)
    write_run_record("bench-collect", args.run_record, task=args.task, device=args.device, results=out)
    print(json.dumps(out))
    return 0


def bench_train(args: BenchTrainArgs) -> int:
    from ..bench_train import bench_train as measure  # deferred: torch is slow to import

    out = measure(
        args.dataset_path,
        batch_size=args.batch_size,
        steps=args.steps,
        device=args.device,
        preset=args.preset,
        bf16=args.bf16,
        channels_last=args.channels_last,
        cudnn_benchmark=args.cudnn_benchmark,
        compile=args.compile,
        native_norms=args.native_norms,
        bf16_norms=args.bf16_norms,
        profile=args.profile,
        **args.key_overrides(),
    )
    write_run_record("bench-train", args.run_record, task=out.get("task"), device=args.device, results=out)
    print(json.dumps(out))
    return 0


def bench_refusals(args: BenchRefusalsArgs) -> int:
    from .bench_refusals import bench_refusals as measure  # deferred: its sample files need h5py, zarr and torch

    def progress(case: dict) -> None:
        if not case["refused"]:
            print(
                f"not refused as the table says: newton-lab {case['argv']} (exit {case['exit']}, one line "
                f"{case['one_line']}, words {case['words']}, folder unchanged {case['unchanged']})",
                file=sys.stderr,
            )

    out = measure(args.only, on_case=progress)
    write_run_record("bench-refusals", args.run_record, task=None, device="cpu", results=out)
    print(json.dumps({k: v for k, v in out.items() if k != "per_case"}))
    return 0 if out["refused"] == out["cases"] else 1
