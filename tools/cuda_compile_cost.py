"""Seconds of CUDA compilation per Warp module of a run, measured without a GPU.

Runs a small job on the CPU (a PickCube collect, or a Mimic generation from ``--source``), then compiles every
Warp module the job loaded for a CUDA architecture with ``wp.compile_aot_module`` (NVRTC runs on the host; no
driver needed) and prints each module's seconds, largest first, and the total: what a cold kernel cache costs
the first run on that GPU, module by module. Set ``NEWTON_LAB_WARP_BACKWARD=1`` to see the cost with adjoints.

    python tools/cuda_compile_cost.py [--job collect|mimic] [--source D.hdf5] [--arch 90] [--skip NAME,...]
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time

import warp as wp

import newton_lab  # noqa: F401  its Warp settings, before Warp creates any module


def run_job(job: str, task: str, source: str | None, out_dir: str) -> None:
    """The CPU job whose modules are measured (2 envs: only which modules load matters, not the rate)."""
    if job == "mimic":
        from newton_lab.mimic.generate import mimic

        mimic(source, episodes=1, num_envs=2, output_path=f"{out_dir}/mimic.hdf5", seed=7, device="cpu", progress=False)
    else:
        from newton_lab.cli import main

        main(
            [
                "collect",
                "--task",
                task,
                "--num-envs",
                "2",
                "--episodes",
                "1",
                "--device",
                "cpu",
                "--no-progress",
                "--dataset-path",
                f"{out_dir}/collect.zarr",
                "--cameras",
                "none",
            ]
        )


def loaded_modules() -> list:
    # Warp lists its modules only in this registry (no public API); a module that ran holds an executable.
    from warp._src.context import user_modules

    return [m for m in user_modules.values() if any(m.execs.values())]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--job", choices=("collect", "mimic"), default="collect")
    p.add_argument("--task", default="GalbotG1-PickCube-v0", help="task of the collect job")
    p.add_argument("--source", help="source dataset of the mimic job (e.g. a StackCube collect)")
    p.add_argument("--arch", type=int, default=90, help="CUDA compute capability (90: H100/H200)")
    p.add_argument("--skip", default="", help="comma-separated parts of module names not to compile")
    args = p.parse_args(argv)
    if args.job == "mimic" and not args.source:
        p.error("--job mimic needs --source (a dataset of the task, e.g. from newton-lab collect)")
    skip = [s for s in args.skip.split(",") if s]
    with tempfile.TemporaryDirectory(prefix="cuda_compile_cost_") as tmp:
        run_job(args.job, args.task, args.source, tmp)
        rows = []
        for module in loaded_modules():
            name = re.sub(r"_[0-9a-f]{8}$", "", module.name)  # unique modules end in a content hash
            if any(s in module.name for s in skip):
                print(f"  skipped {name}", flush=True)
                continue
            t = time.perf_counter()
            wp.compile_aot_module(module, arch=args.arch, module_dir=f"{tmp}/sm{args.arch}")
            rows.append((time.perf_counter() - t, name))
            print(f"{rows[-1][0]:7.1f} s  {name}", flush=True)
    print(f"\nsm_{args.arch}, enable_backward={wp.config.enable_backward}, {len(rows)} modules, largest first:")
    for seconds, name in sorted(rows, reverse=True)[:10]:
        print(f"{seconds:7.1f} s  {name}")
    print(f"{sum(s for s, _ in rows):7.1f} s  in all")
    return 0


if __name__ == "__main__":
    sys.exit(main())
