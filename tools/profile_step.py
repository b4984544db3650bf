"""Where a bare solver step spends its GPU time: Warp's per-kernel CUDA timing of ``cfg.decimation`` solver
substeps (the step's physics alone: no actions, task, reset or observation), summed by the stage its kernel's
module belongs to, for the model the task's env hands its solver (idle joints welded and their links merged,
``PhysicsCfg.weld_idle_joints``) and, with ``--full``, for the full robot beside it.

    python tools/profile_step.py [--task GalbotG1-PickCube-v0] [--num-envs 1024 4096 16384] [--steps 20]
                                 [--full] [--top 12] [--device cuda:0]

One JSON line per variant and env count: kernel milliseconds per env step, launches, the stages (collision,
constraint build, solver iterations, smooth dynamics, integration, Newton's glue) with their share, and the top
kernels. A kernel's stage is the mujoco_warp module that defines it (``collision_*``, ``constraint``, ``solver``,
``smooth``, ...), read from Warp's module registry rather than guessed from its name. CUDA events around every
launch add a little to each kernel, and the substeps run eagerly: the shares, not the sum, are the figure
(``newton-lab bench`` times the captured step). On the CPU Warp records no activities and the lines say so.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
from collections import defaultdict

import newton
import newton_lab.tasks  # noqa: F401  (registers every task id)
import warp as wp
import warp._src.context as warp_context  # its module registry maps a kernel's key to the module defining it

from newton_lab.envs import make_env
from newton_lab.task_api.registry import lookup

STAGES = (
    ("collision", ("collision",)),
    ("constraint build", ("constraint",)),
    ("solver iterations", ("solver", "block_cholesky")),
    ("smooth dynamics", ("smooth", "passive", "derivative", "support", "sensor")),
    ("integration", ("forward",)),
)
"""mujoco_warp module-name fragments of each stage (first match wins); kernels of other packages (Newton's state
exchange with MuJoCo-Warp) are ``newton glue``."""


def stage_of(module: str) -> str:
    """The stage of a kernel defined in Python module ``module``."""
    if not module.startswith("mujoco_warp"):
        return "newton glue"
    leaf = module.rsplit(".", 1)[-1]
    return next((stage for stage, fragments in STAGES if any(f in leaf for f in fragments)), f"mujoco_warp {leaf}")


def kernel_modules() -> dict[str, str]:
    """Kernel name -> the Python module that defines it, over every kernel Warp has loaded: by key and by the
    mangled name (``<key>_<hash8>``) that Warp's activity timer reports. The Python module comes from the kernel's
    function: a kernel a factory makes (mujoco_warp's ``_crb_accumulate.<locals>.kernel``) lives in a Warp module
    of its own, named after the kernel, not after the file that defines it."""
    out: dict[str, str] = {}
    for module_name, module in list(warp_context.user_modules.items()):
        for kernel in list(module._live_kernels):  # every variant a factory made, not only the latest per key
            name = getattr(getattr(kernel, "func", None), "__module__", None) or module_name
            out.setdefault(kernel.key, name)
            try:
                out.setdefault(kernel.get_mangled_name(), name)
            except RuntimeError:  # never compiled: it cannot have run
                pass
    return out


def module_of(activity: str, modules: dict[str, str]) -> str:
    """The module of a timed kernel (``<key>_<hash8>``); ``""`` when unknown."""
    return modules.get(activity) or modules.get(re.sub(r"_[0-9a-f]{8}$", "", activity), "")


def profile(cfg, model: newton.Model, steps: int, top: int) -> dict:
    """GPU milliseconds per env step (``cfg.decimation`` solver substeps) of ``model``: total, by stage, top
    kernels."""
    solver = newton.solvers.SolverMuJoCo(model, **cfg.physics.solver_options())
    solver.mjw_model.opt.warn_overflow = 0
    state, control = model.state(), model.control()
    newton.eval_fk(model, state.joint_q, state.joint_qd, state)
    with wp.ScopedDevice(model.device):
        for _ in range(3 * cfg.decimation):  # warm up: every kernel compiled and loaded
            solver.step(state, state, control, None, cfg.sim_dt)
        wp.synchronize_device(model.device)
        wp.timing_begin(cuda_filter=wp.TIMING_KERNEL)
        for _ in range(steps * cfg.decimation):
            solver.step(state, state, control, None, cfg.sim_dt)
        results = wp.timing_end()
    modules = kernel_modules()
    per_kernel: dict[str, float] = defaultdict(float)
    per_stage: dict[str, float] = defaultdict(float)
    for r in results:
        key = r.name.removeprefix("forward kernel ")
        per_kernel[key] += r.elapsed / steps
        per_stage[stage_of(module_of(key, modules))] += r.elapsed / steps
    total = sum(per_kernel.values())
    if not results:
        return {"note": f"no CUDA activity recorded on {model.device} (Warp times kernels on CUDA devices only)"}
    ranked = sorted(per_kernel.items(), key=lambda kv: -kv[1])[:top]
    return {
        "kernel_ms_per_env_step": round(total, 4),
        "launches_per_env_step": len(results) / steps,
        "stages": {
            k: {"ms": round(v, 4), "share": round(v / total, 3)}
            for k, v in sorted(per_stage.items(), key=lambda kv: -kv[1])
        },
        "top_kernels": [{"kernel": k, "ms": round(v, 4), "share": round(v / total, 3)} for k, v in ranked],
    }


def solver_model(task: str, num_envs: int, device, weld: bool) -> tuple:
    """The task's config and the model its env's solver steps: the task's own physics (idle joints welded) or,
    ``weld=False``, every joint simulated."""
    physics = None if weld else dataclasses.replace(lookup(task).make_cfg({}).physics, weld_idle_joints=False)
    env = make_env(task, num_envs=num_envs, device=device, seed=0, cameras=False, capture=False, physics=physics)
    return env.cfg, (env.model if env.sim.joint_space is None else env.sim.joint_space.model)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="GalbotG1-PickCube-v0")
    ap.add_argument("--num-envs", type=int, nargs="+", default=[1024, 4096, 16384])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--top", type=int, default=12)
    ap.add_argument("--full", action="store_true", help="also profile the full robot (no joint welded)")
    ap.add_argument("--device", default="cuda:0")
    args = ap.parse_args()
    device = wp.get_device(args.device)
    for n in args.num_envs:
        for variant, weld in (("task", True), ("full", False))[: 2 if args.full else 1]:
            cfg, model = solver_model(args.task, n, device, weld)
            row = {
                "task": args.task,
                "variant": variant,
                "device_name": device.name,
                "num_envs": n,
                "decimation": cfg.decimation,
                "dofs_per_world": model.joint_dof_count // model.world_count,
                "bodies_per_world": model.body_count // model.world_count,
            }
            print(json.dumps({**row, **profile(cfg, model, args.steps, args.top)}), flush=True)


if __name__ == "__main__":
    main()
