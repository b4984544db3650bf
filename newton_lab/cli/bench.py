"""``newton-lab bench``, ``bench-collect``, ``bench-train``, ``bench-refusals``, ``suite`` and ``results``:
measurements, each written as a run record, and the results page built from the records (arguments:
``newton_lab.commands.bench``)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..commands import (
    BenchArgs,
    BenchCollectArgs,
    BenchRefusalsArgs,
    BenchTrainArgs,
    ResultsArgs,
    SuiteArgs,
    camera_option,
)
from ..flows.settings import configure
from ..flows.suite_rows import rows_of
from ..records import command_wall_s, default_path, make_record, write_record
from ..results import update
from . import watchdog


def write_run_record(kind: str, args, task: str | None, device: str | None, results: dict) -> None:
    """The benchmark's run record at ``--run-record`` (default under outputs/records/); its path on stderr."""
    rec = make_record(kind, task=task, device=device, results=results, wall_s=command_wall_s())
    path = write_record(rec, args.run_record or default_path(kind, task))
    print(f"run record: {path}", file=sys.stderr)


def bench(args: BenchArgs) -> int:
    from ..bench import bench as measure  # deferred: Warp/Newton are slow to import

    cam = (
        {}
        if args.camera is None
        else {
            "camera": args.camera,
            "resolution": tuple(args.resolution or (128, 128)),
            "camera_data": tuple(args.camera_data or ("rgb",)),
        }
    )
    out = measure(args.task, num_envs=args.num_envs, steps=args.steps, device=args.device, **cam)
    write_run_record("bench", args, args.task, args.device, out)
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
    write_run_record("bench-collect", args, args.task, args.device, out)
    print(json.dumps(out))
    return 0


def bench_train(args: BenchTrainArgs) -> int:
    from ..bench import bench_train as measure  # deferred: torch is slow to import

    out = measure(
        args.dataset_path,
        batch_size=args.batch_size,
        steps=args.steps,
        device=args.device,
        preset=args.preset,
        bf16=args.bf16,
    )
    write_run_record("bench-train", args, out.get("task"), args.device, out)
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
    write_run_record("bench-refusals", args, None, "cpu", out)
    print(json.dumps({k: v for k, v in out.items() if k != "per_case"}))
    return 0 if out["refused"] == out["cases"] else 1


def suite(args: SuiteArgs) -> int:
    rows = rows_of(args.recipe, args.only)
    if args.dry_run:
        for row in rows:
            print(f"{row.name}: newton-lab {' '.join(row.command(Path(args.out), '<UTC time>'))}")
        return 0
    watchdog.start()  # killed, it leaves neither its Prefect server nor the row's command running
    configure(Path(args.out) / ".prefect")  # before Prefect is imported
    from ..flows.suite import suite as run_suite  # deferred: Prefect is slow to import, and after configure

    summary = run_suite(
        recipe=args.recipe, out=str(Path(args.out).resolve()), records=args.records, page=args.page, only=args.only
    )
    for r in summary["rows"]:
        state = "ok" if r["exit"] == 0 else f"failed (exit {r['exit']})"
        print(f"{r['row']:<32} {state:<18} {r.get('record', '')}")
    print(
        json.dumps(
            {
                "recipe": args.recipe,
                "failed": [r["row"] for r in summary["rows"] if r["exit"] != 0],
                "page": summary.get("page"),
            }
        )
    )
    return 0 if all(r["exit"] == 0 for r in summary["rows"]) else 1


def results(args: ResultsArgs) -> int:
    fresh = update(args.page, args.records, check=args.check)
    if args.check and not fresh:
        print(
            f"{args.page} does not match the run records in {args.records}; run `newton-lab results` to regenerate it",
            file=sys.stderr,
        )
        return 1
    print(f"{args.page}: {'up to date' if fresh else 'regenerated'} from {args.records}")
    return 0
