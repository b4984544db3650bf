"""Where a bare solver step spends its GPU time: Warp's per-kernel CUDA timing of ``env.simulate()`` (the step's
physics alone: ``decimation`` solver substeps, no actions, task, reset or observation), grouped by kernel name.

    python tools/profile_step.py --task GalbotG1-PickCube-v0 --num-envs 1024 4096 16384 --steps 20

One JSON line per env count: milliseconds per env step in all kernels, and the top kernels with their share. The
grouping follows mujoco_warp's kernel names (collision broad / narrow phase, constraint build, solver iterations,
smoothing and integration). CUDA events around every launch add a little to each kernel; the shares, not the sum,
are the figure (``newton-lab bench`` times the captured step).
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict

import warp as wp

from newton_lab.envs import make_env

STAGES = (
    ("collision", re.compile(r"collision|broad|narrow|sap|nxn|contact|gjk|epa|box_box|plane|sphere|capsule|ccd")),
    ("solver", re.compile(r"solve|linesearch|cg_|hessian|update_gradient|mul_m|cholesky|jtdacj|init_h")),
    ("constraint", re.compile(r"constraint|efc|_jac|contact_to|make_")),
    ("smooth / kinematics", re.compile(r"kinematic|fk|articulation|com_|crb|cfrc|rne_|gravity|tendon|transmission|"
                                       r"smooth|cdof|cinert|factor_m")),
    ("integration", re.compile(r"euler|implicit|integrat|advance|qvel|qpos")),
)
"""Kernel-name patterns of each stage, matched on the kernel's own name (first match wins; the rest is ``other``)."""


def stage_of(name: str) -> str:
    """The stage of a Warp activity name such as ``forward kernel _crb_accumulate__locals__kernel_eb71fb91``."""
    core = re.sub(r"^forward kernel |__locals__.*$", "", name).lower()
    return next((stage for stage, pattern in STAGES if pattern.search(core)), "other")


def profile(task: str, num_envs: int, steps: int, top: int) -> dict:
    env = make_env(task, num_envs=num_envs, device="cuda:0", seed=0, randomize=True, cameras=False)
    for _ in range(3):  # warm up: every kernel compiled and loaded
        env.simulate()
    wp.synchronize_device(env.device)
    wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
    for _ in range(steps):
        env.simulate()
    results = wp.timing_end()
    per_kernel: dict[str, float] = defaultdict(float)
    for r in results:
        per_kernel[r.name] += r.elapsed / steps
    total = sum(per_kernel.values())
    per_stage: dict[str, float] = defaultdict(float)
    for name, ms in per_kernel.items():
        per_stage[stage_of(name)] += ms
    ranked = sorted(per_kernel.items(), key=lambda kv: -kv[1])[:top]
    return {"task": task, "device_name": env.device.name, "num_envs": num_envs, "decimation": env.cfg.decimation,
            "kernel_ms_per_env_step": round(total, 4), "launches_per_env_step": len(results) / steps,
            "stages": {k: {"ms": round(v, 4), "share": round(v / total, 3)} for k, v in
                       sorted(per_stage.items(), key=lambda kv: -kv[1])},
            "top_kernels": [{"kernel": k, "ms": round(v, 4), "share": round(v / total, 3)} for k, v in ranked]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--task", default="GalbotG1-PickCube-v0")
    ap.add_argument("--num-envs", type=int, nargs="+", default=[1024, 4096, 16384])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--top", type=int, default=12)
    args = ap.parse_args()
    for n in args.num_envs:
        print(json.dumps(profile(args.task, n, args.steps, args.top)), flush=True)


if __name__ == "__main__":
    main()
