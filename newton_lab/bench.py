"""Throughput of the full captured env step against the bare solver on the identical model.

Both are measured side by side in one process: the env's captured step (actions -> decimation solver
steps -> task kernel -> masked resets -> observations) and a graph of just ``decimation`` solver steps. Also the
diffusion-policy training step (``bench_train``); expert collection (``bench-collect``) is ``bench_collect``'s.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from typing import Any

import torch
import warp as wp
from newton.sensors import SensorCamera

from .envs import make_env
from .policies.data import SequenceDataset
from .policies.diffusion import PRESETS, DiffusionPolicy, DiffusionPolicyConfig
from .policies.train_step import CudaGraphTrainStep, EagerTrainStep
from .task_api.physics import PhysicsCfg


def _time_graph(launch, steps: int, device) -> float:
    for _ in range(3):
        launch()
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(steps):
        launch()
    wp.synchronize_device(device)
    return (time.perf_counter() - t0) / steps


def bench(
    task_id: str,
    *,
    num_envs: int = 4,
    steps: int = 200,
    device: str | None = None,
    camera: str | None = None,
    resolution: tuple[int, int] = (128, 128),
    camera_data: tuple[str, ...] = ("rgb",),
    cameras: dict[str, Any] | None = None,
    physics: PhysicsCfg | None = None,
) -> dict[str, Any]:
    """Env-steps/s, bare world-steps/s and their per-step time ratio (env step / decimation solver steps).
    ``physics`` replaces the task's physics settings (``make_env``; ``tools/physics_table.py`` compares them).
    With ``camera``: also env-steps/s with that camera rendered every step (``resolution`` (w, h) [px],
    ``camera_data`` of rgb / depth / segmentation) against the camera ceiling measured beside it; ``cameras``
    (``make_env``'s dict, e.g. ``{"front_head": {"resolution": (96, 72)}, "left_wrist": ...}``) instead: several
    views rendered every step, the ceiling rendering each of them bare."""
    if camera is not None:
        cameras = {camera: {"resolution": tuple(resolution), "data": tuple(camera_data)}}
    cams = cameras or False
    env = make_env(task_id, num_envs=num_envs, device=device, seed=0, cameras=cams, physics=physics)
    step_graph = env.sim.step_graph
    if step_graph is None:
        raise RuntimeError(f"step capture is unavailable on {env.device}; benchmark needs Warp graph capture")
    env.buffers.actions.copy_(env.current_action())
    with wp.ScopedDevice(env.device):
        with wp.ScopedCapture(device=env.device) as cap:
            env.sim.simulate()
    bare_graph = cap.graph
    t_env = _time_graph(lambda: wp.capture_launch(step_graph), steps, env.device)
    t_bare = _time_graph(lambda: wp.capture_launch(bare_graph), steps, env.device)
    # the Python-facing step (validation + copy + launch) on the same env
    a = env.current_action()
    t_api = _time_graph(lambda: env.step(a), max(steps // 4, 1), env.device)
    dec = env.cfg.decimation
    out = {
        "task": task_id,
        "device": str(env.device),
        "device_name": torch.cuda.get_device_name() if env.device.is_cuda else "cpu",
        "num_envs": num_envs,
        "decimation": dec,
        "env_steps_per_s": num_envs / t_env,
        "env_steps_per_s_python_step": num_envs / t_api,
        "bare_world_steps_per_s": num_envs * dec / t_bare,
        "ratio_env_step_to_bare": t_env / t_bare,
    }
    if cams:
        out.update(_camera_figures(env, list(env.sensors.camera_specs), steps))
    return out


def _camera_figures(env, names: list[str], steps: int) -> dict[str, Any]:
    """The env step plus its camera render (both captured, launched back to back, as ``env.step`` followed by
    reading ``env.sensors.images``) against the ceiling: the bare solver graph plus a bare ``SensorCamera`` render of
    each view per world at the same poses and resolution (one BVH refit, then one render per view; captured)."""
    env.render()  # builds and captures the render graph
    cams = env.sensors.cameras
    render_graph = cams.render_graph
    if render_graph is None:
        raise RuntimeError(f"camera render capture is unavailable on {env.device}")
    with wp.ScopedDevice(env.device):
        sensor = SensorCamera(env.model)
        sensor.create_default_light(enable_shadows=False)
        views = [_bare_view(sensor, cams, name, env.num_envs) for name in names]

        def bare_render():
            env.model.bvh_refit_shapes(env.state)
            for poses, rays, images in views:
                sensor.update(env.state, poses, rays, **images)

        bare_render()  # compiles before the capture
        with wp.ScopedCapture(device=env.device) as cap:
            env.sim.simulate()  # the bare solver steps (a graph launch inside a capture is CUDA-only)
            bare_render()
    ceiling_graph = cap.graph

    step_graph = env.sim.step_graph

    def env_with_camera():
        wp.capture_launch(step_graph)
        wp.capture_launch(render_graph)

    t_cam = _time_graph(env_with_camera, steps, env.device)
    t_ceiling = _time_graph(lambda: wp.capture_launch(ceiling_graph), steps, env.device)
    mem = None
    if env.device.is_cuda:
        free, total = torch.cuda.mem_get_info(env.device.ordinal)
        mem = (total - free) / 2**20 / env.num_envs
    first = cams.specs[names[0]]
    return {
        "camera": "+".join(names),
        "resolution": [first.width, first.height],
        "camera_data": list(first.data),
        "cameras": {n: [cams.specs[n].width, cams.specs[n].height, list(cams.specs[n].data)] for n in names},
        "env_steps_per_s_with_camera": env.num_envs / t_cam,
        "ceiling_env_steps_per_s": env.num_envs / t_ceiling,
        "ratio_camera_env_to_ceiling": t_ceiling / t_cam,
        "gpu_mem_used_mib_per_env": mem,
    }


def _bare_view(sensor, cams, name: str, num_envs: int):
    """View ``name``'s camera poses, the env's own pinhole rays for it, and bare output images of its size and data."""
    spec = cams.specs[name]
    rays = next(g.rays for g in cams.view_groups if name in g.cameras)
    w, h, data = spec.width, spec.height, spec.data
    images = {
        "color_image": sensor.allocate_image_color(num_envs, w, h) if "rgb" in data else None,
        "depth_image": sensor.allocate_image_depth(num_envs, w, h) if "depth" in data else None,
        "shape_index_image": sensor.allocate_image_shape_index(num_envs, w, h) if "segmentation" in data else None,
    }
    return wp.from_torch(cams.poses(name).contiguous(), dtype=wp.transformf), rays, images


def bench_train(
    dataset: str,
    *,
    batch_size: int = 1024,
    steps: int = 200,
    device: str = "cpu",
    preset: str = "default",
    bf16: bool = False,
    channels_last: bool = False,
    obs_keys: tuple[str, ...] | None = None,
    image_keys: tuple[str, ...] | None = None,
    cudnn_benchmark: bool = False,
    compile: bool = False,
) -> dict[str, Any]:
    """Diffusion-policy optimiser steps/s on ``dataset``: the eager step and (on CUDA) the captured step, side by
    side in one process on fresh policies of the same architecture; with ``bf16`` each also under bfloat16
    autocast (keys ``..._bf16``), with ``channels_last`` each also with the network's weights in channels-last
    layout (keys ``..._cl``: the convolutions then run channels-last); ``obs_keys`` / ``image_keys`` replace the
    preset's (e.g. the long-horizon recipe's two views); with ``cudnn_benchmark`` each also with cuDNN's autotuner
    on (keys ``..._tuned``); with ``compile`` the eager step also through ``torch.compile`` at the last variant's
    precision and autotuning (key ``EagerTrainStep_compiled...``). Also where a step's time goes
    (``step_breakdown``), the achieved TFLOP/s at the fastest variant's rate and, on CUDA, the peak GPU memory."""
    fields = {k: v for k, v in PRESETS[preset].items() if k not in ("batch_size", "max_steps", "epochs")}
    fields.update({k: v for k, v in (("obs_keys", obs_keys), ("image_keys", image_keys)) if v})
    cfg = DiffusionPolicyConfig(**fields, batch_size=batch_size, device=device)
    data = SequenceDataset(
        dataset,
        pred_horizon=cfg.pred_horizon,
        obs_horizon=cfg.obs_horizon,
        obs_keys=cfg.obs_keys,
        image_keys=cfg.image_keys,
    )
    on_cuda = torch.device(device).type == "cuda"
    kinds = [EagerTrainStep] + ([CudaGraphTrainStep] if on_cuda else [])
    out: dict[str, Any] = {
        "dataset": dataset,
        "device": device,
        "batch_size": batch_size,
        "preset": preset,
        "device_name": torch.cuda.get_device_name(device) if on_cuda else "cpu",
        "windows": len(data),
        "obs_keys": list(cfg.obs_keys or ()),
        "image_keys": list(data.image_keys),
        "image_shapes": {k: list(v) for k, v in data.image_shapes.items()},
    }
    both = {True: [False, True], False: [False]}
    grid = [
        (kind, tuned, layout_cl, precision, False)
        for tuned, layout_cl, precision, kind in itertools.product(
            both[cudnn_benchmark], both[channels_last], both[bf16], kinds
        )
    ]  # the autotuner last: once on, it stays on in the process
    grid += [(EagerTrainStep, cudnn_benchmark, False, bf16, True)] if compile else []
    for kind, tuned, layout_cl, precision, compiled in grid:
        torch.backends.cudnn.benchmark = tuned
        tags = (("_compiled", compiled), ("_bf16", precision), ("_cl", layout_cl), ("_tuned", tuned))
        name = kind.__name__ + "".join(tag for tag, on in tags if on)
        run_cfg = dataclasses.replace(cfg, bf16=precision, compile=compiled)
        rate, final = _time_variant(kind, data, run_cfg, layout_cl, steps)
        out[f"{name}_steps_per_s"] = rate
        out[f"{name}_samples_per_s"] = rate * batch_size
        out[f"{name}_final_loss"] = final
    if len(kinds) == 2:
        out["speedup"] = out["CudaGraphTrainStep_steps_per_s"] / out["EagerTrainStep_steps_per_s"]
    out.update(step_breakdown(data, dataclasses.replace(cfg, bf16=bf16), steps=min(steps, 20)))
    best = max(v for k, v in out.items() if k.endswith("_samples_per_s"))
    out["achieved_tflops"] = out["flops_per_sample"] * best / 1e12  # at the fastest variant's samples/s
    if on_cuda:
        out["gpu_mem_peak_mib"] = torch.cuda.max_memory_allocated(device) / 2**20
    return out


def _time_variant(kind, data: SequenceDataset, cfg: DiffusionPolicyConfig, channels_last: bool, steps: int):
    """(steps/s, final loss) of ``steps`` optimiser steps of ``kind`` on a fresh policy (seed 0), after 10 untimed
    ones (allocation, autotuning, capture, compilation)."""
    torch.manual_seed(0)
    policy = DiffusionPolicy.from_dataset(data, cfg).to(cfg.device)
    if channels_last:
        policy.model.to(memory_format=torch.channels_last)
    on_cuda = torch.device(cfg.device).type == "cuda"
    stepper, done, t0, loss = kind(policy, data, cfg), 0, 0.0, None
    while done < steps + 10:
        for loss in stepper.epoch():  # noqa: B007 - the last step's loss is read after the loop
            done += 1
            if done == 10:
                if on_cuda:
                    torch.cuda.synchronize(cfg.device)
                t0 = time.perf_counter()
            if done == steps + 10:
                break
    final = loss.item()  # waits for the queued steps
    return steps / (time.perf_counter() - t0), final


def step_breakdown(data: SequenceDataset, cfg: DiffusionPolicyConfig, steps: int = 20) -> dict[str, Any]:
    """Where one training step's time goes, each stage timed apart with the device synchronised around it
    (``breakdown_ms``: the batch's gather from the windows, the forward pass and loss, the backward pass, the
    optimiser step with the EMA update; eager, so the sum exceeds a captured step), and the step's floating-point
    work (``flops_per_sample``: forward and backward, counted by ``torch.utils.flop_counter`` on one step)."""
    from torch.utils.flop_counter import FlopCounterMode  # deferred: only this measurement counts operations

    torch.manual_seed(0)
    device = torch.device(cfg.device)
    policy = DiffusionPolicy.from_dataset(data, cfg).to(device)
    opt = torch.optim.AdamW(policy.model.parameters(), lr=cfg.lr, fused=device.type in ("cuda", "cpu"))
    obs, actions = data.obs.to(device), data.actions.to(device)
    images = {k: v.to(device) for k, v in data.images.items()}
    obs_index, action_index = data.obs_index.to(device), data.action_index.to(device)
    gen = torch.Generator(device=device).manual_seed(0)

    def sync() -> float:
        if device.type == "cuda":
            torch.cuda.synchronize(device)
        return time.perf_counter()

    def batch() -> dict[str, Any]:
        idx = torch.randint(len(data), (cfg.batch_size,), device=device, generator=gen)
        frames = obs_index[idx]
        out = {"obs": obs[frames], "actions": actions[action_index[idx]]}
        if images:
            out["images"] = {k: v[frames] for k, v in images.items()}
        return out

    spent = {"data": 0.0, "forward": 0.0, "backward": 0.0, "optimizer": 0.0}
    warmup = 3
    for i in range(steps + warmup):
        t0 = sync()
        b = batch()
        t1 = sync()
        loss = policy.compute_loss(b)
        t2 = sync()
        loss.backward()
        t3 = sync()
        opt.step()
        opt.zero_grad(set_to_none=True)
        policy.ema.update(policy.model)
        t4 = sync()
        if i >= warmup:
            for name, dt in zip(spent, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
                spent[name] += dt
    with FlopCounterMode(display=False) as counter:
        policy.compute_loss(batch()).backward()
    opt.zero_grad(set_to_none=True)
    return {
        "breakdown_ms": {k: 1e3 * v / steps for k, v in spent.items()},
        "flops_per_sample": counter.get_total_flops() / cfg.batch_size,
    }


from .bench_collect import bench_collect, bench_collect_on_workers  # noqa: E402,F401 - re-exported (the CLI)
