"""Where a task's bare solver step spends its GPU time: every kernel of ``cfg.decimation`` solver steps timed with
Warp's CUDA activity timer (``wp.timing_begin``), summed by the stage its module belongs to (collision, constraint
build, solver iterations, smooth dynamics, ...), for the full G1 and for the robot welded down to the joints the
task moves (``tools/frozen_dof_probe.py``), at each ``--num-envs``.

    python tools/solver_profile.py [--task GalbotG1-PickCube-v0] [--num-envs 1024 4096 16384] [--steps 20]
                                   [--device cuda:0] [--top 12]

The steps run eagerly (a captured graph is timed as one activity), so the per-kernel times add up to a bit more
than a captured step's wall time; the shares are what the profile is for. It prints one JSON line per variant and
size: ms per control step by stage, the share of each, and the ``--top`` kernels. On the CPU the activity timer
records nothing and the lines say so.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict

import newton
import warp as wp
import warp._src.context as warp_context  # the module registry maps a kernel's key to its Python module

import newton_lab.tasks  # noqa: F401  (registers every task id)
from newton_lab.task_api.registry import lookup

from frozen_dof_probe import MOVING, build, welded_mjcf
from newton_lab.envs.scene import task_posture
from newton_lab.robots.registry import robot_binding

STAGES = (
    ("collision", ("collision",)),
    ("constraint build", ("constraint",)),
    ("solver iterations", ("solver", "block_cholesky")),
    ("smooth dynamics", ("smooth", "passive", "derivative", "support", "sensor")),
    ("integration", ("forward",)),
)
"""mujoco_warp module name fragments per stage; kernels of any other module (Newton's state exchange) are
``newton glue``."""


def stage_of(module: str) -> str:
    """The profile stage of a kernel's Python module."""
    if module.startswith("mujoco_warp"):
        leaf = module.rsplit(".", 1)[-1]
        for stage, fragments in STAGES:
            if any(f in leaf for f in fragments):
                return stage
        return f"mujoco_warp other ({leaf})"
    return "newton glue"


def kernel_modules() -> dict[str, str]:
    """Kernel key -> Python module name, over every module Warp has seen."""
    out = {}
    for name, module in warp_context.user_modules.items():
        for key in module.kernels:
            out.setdefault(key, name)
    return out


def profile(cfg, model: newton.Model, steps: int, top: int) -> dict:
    """Per control step (``cfg.decimation`` solver steps): GPU ms by stage and the ``top`` kernels."""
    solver = newton.solvers.SolverMuJoCo(model, **cfg.physics.solver_options())
    solver.mjw_model.opt.warn_overflow = 0
    state, control = model.state(), model.control()
    newton.eval_fk(model, state.joint_q, state.joint_qd, state)
    with wp.ScopedDevice(model.device):
        for _ in range(2 * cfg.decimation):  # compiles, settles
            solver.step(state, state, control, None, cfg.sim_dt)
        wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
        for _ in range(steps * cfg.decimation):
            solver.step(state, state, control, None, cfg.sim_dt)
        results = wp.timing_end()
    modules = kernel_modules()
    by_stage: dict[str, float] = defaultdict(float)
    by_kernel: dict[str, float] = defaultdict(float)
    for r in results:
        key = r.name.removeprefix("forward kernel ").removeprefix("backward kernel ")
        by_stage[stage_of(modules.get(key, ""))] += r.elapsed / steps
        by_kernel[key] += r.elapsed / steps
    total = sum(by_stage.values())
    return {
        "dofs_per_world": model.joint_dof_count // model.world_count,
        "ms_per_step": round(total, 4),
        "stages_ms": {k: round(v, 4) for k, v in sorted(by_stage.items(), key=lambda kv: -kv[1])},
        "stages_share": {k: round(v / total, 3) for k, v in sorted(by_stage.items(), key=lambda kv: -kv[1])}
        if total else {},
        "top_kernels_ms": {k: round(v, 4) for k, v in sorted(by_kernel.items(), key=lambda kv: -kv[1])[:top]},
        "note": "" if results else "no CUDA activity recorded (the CPU has no activity timer)",
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="GalbotG1-PickCube-v0")
    ap.add_argument("--num-envs", type=int, nargs="+", default=[1024, 4096, 16384])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--device", default=None)
    ap.add_argument("--top", type=int, default=12)
    args = ap.parse_args()
    cfg = lookup(args.task).make_cfg(None)
    welded = welded_mjcf(task_posture(cfg, robot_binding(cfg.robot)), MOVING)
    device = wp.get_device(args.device)
    for n in args.num_envs:
        for variant, mjcf in (("full", None), ("welded", welded)):
            model = build(cfg, n, device, mjcf)
            row = {"task": args.task, "variant": variant, "device": str(device), "gpu": device.name, "num_envs": n}
            print(json.dumps({**row, **profile(cfg, model, args.steps, args.top)}), flush=True)


if __name__ == "__main__":
    main()
