"""Throughput of the full captured env step against the bare solver on the identical model.

Both are measured side by side in one process: the env's captured step (actions -> decimation solver
steps -> task kernel -> masked resets -> observations) and a graph of just ``decimation`` solver steps. The
diffusion-policy training step is ``bench_train``'s; expert collection (``bench-collect``) is ``bench_collect``'s.
"""

from __future__ import annotations

import time
from typing import Any

import torch
import warp as wp
from newton.sensors import SensorCamera

from .envs import make_env
from .envs.render_settings import RENDER_BLOCK_DIM, RENDER_ORDER, RENDER_TILE, render_config
from .records import EVERY_SHAPE
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
    render_orders: bool = False,
) -> dict[str, Any]:
    """Env-steps/s, bare world-steps/s and their per-step time ratio (env step / decimation solver steps).
    ``physics`` replaces the task's physics settings (``make_env``; ``tools/physics_table.py`` compares them).
    With ``camera``: also env-steps/s with that camera rendered every step (``resolution`` (w, h) [px],
    ``camera_data`` of rgb / depth / segmentation) against the camera ceiling measured beside it; ``cameras``
    (``make_env``'s dict, e.g. ``{"front_head": {"resolution": (96, 72)}, "left_wrist": ...}``) instead: several
    views rendered every step, the ceiling rendering each of them bare. ``render_orders``: also both under each of
    the renderer's traversal orders, tile and thread-block sizes (``by_render_order``, ``RENDER_SWEEP``; the env
    renders with ``envs.render_settings``')."""
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
        out.update(_camera_figures(env, list(env.sensors.camera_specs), steps, render_orders))
    return out


def _camera_figures(env, names: list[str], steps: int, render_orders: bool = False) -> dict[str, Any]:
    """The env step plus its camera render (both captured, launched back to back, as ``env.step`` followed by
    reading ``env.sensors.images``) against the ceiling: the bare solver graph plus a bare ``SensorCamera`` render of
    each view per world at the same poses, resolution and render settings (one BVH refit, then one render per view;
    captured). ``render_orders``: both again under every setting of ``RENDER_SWEEP``."""
    env.render()  # builds and captures the render graph
    cams = env.sensors.cameras
    render_graph = cams.render_graph
    if render_graph is None:
        raise RuntimeError(f"camera render capture is unavailable on {env.device}")
    max_distance = cams.robot.camera_clipping[1]
    with wp.ScopedDevice(env.device):
        sensor = SensorCamera(env.model, default_render_config=render_config(max_distance))
        sensor.create_default_light(enable_shadows=False)
        views = [_bare_view(sensor, cams, name, env.num_envs) for name in names]

        def ceiling_graph(config=None):
            def bare_render():
                env.model.bvh_refit_shapes(env.state)
                for poses, rays, images in views:
                    sensor.update(env.state, poses, rays, render_config=config, **images)

            bare_render()  # compiles before the capture
            with wp.ScopedCapture(device=env.device) as cap:
                env.sim.simulate()  # the bare solver steps (a graph launch inside a capture is CUDA-only)
                bare_render()
            return cap.graph

        ceiling = ceiling_graph()

    step_graph = env.sim.step_graph

    def env_with_camera():
        wp.capture_launch(step_graph)
        wp.capture_launch(render_graph)

    t_cam = _time_graph(env_with_camera, steps, env.device)
    t_ceiling = _time_graph(lambda: wp.capture_launch(ceiling), steps, env.device)
    mem = None
    if env.device.is_cuda:
        free, total = torch.cuda.mem_get_info(env.device.ordinal)
        mem = (total - free) / 2**20 / env.num_envs
    first = cams.specs[names[0]]
    out = {
        "camera": "+".join(names),
        "resolution": [first.width, first.height],
        "camera_data": list(first.data),
        "cameras": {n: [cams.specs[n].width, cams.specs[n].height, list(cams.specs[n].data)] for n in names},
        "render_order": f"{_setting_name(RENDER_ORDER, RENDER_TILE)}/{RENDER_BLOCK_DIM}",
        "hidden_link_groups": list(cams.hidden_groups),
        "rendered_shapes": int(env.model.bvh_shape_count_enabled),
        "env_steps_per_s_with_camera": env.num_envs / t_cam,
        "ceiling_env_steps_per_s": env.num_envs / t_ceiling,
        "ratio_camera_env_to_ceiling": t_ceiling / t_cam,
        "gpu_mem_used_mib_per_env": mem,
    }
    if render_orders:
        out["by_render_order"] = _render_order_sweep(env, ceiling_graph, max_distance, steps)
    return out


def _render_order_sweep(env, ceiling_graph, max_distance: float, steps: int) -> dict[str, dict[str, float]]:
    """Env-steps/s of the env step with its camera render, and of the ceiling, under each setting of
    ``RENDER_SWEEP`` (keyed ``ORDER/BLOCK`` or ``TILED_WxH/BLOCK``), and under the env's own setting drawing every
    shape (``... every shape``: the links it leaves out, ``Cameras.hidden_groups``, drawn too); the env renders with
    its own settings after."""
    cams, out = env.sensors.cameras, {}
    for order, tile, block in RENDER_SWEEP:
        cams.use_render_order(order, block, tile)
        config = render_config(max_distance, order, block, tile)
        out[f"{_setting_name(order, tile)}/{block}"] = _rates(env, ceiling_graph, config, steps)
    cams.use_render_order(RENDER_ORDER, RENDER_BLOCK_DIM)
    hidden = cams.hidden_groups
    cams.hide(())  # the env's settings, drawing every shape: what leaving out the unseen links saves
    try:
        every = _rates(env, ceiling_graph, None, steps)
        out[f"{_setting_name(RENDER_ORDER, RENDER_TILE)}/{RENDER_BLOCK_DIM}{EVERY_SHAPE}"] = {
            **every,
            "rendered_shapes": int(env.model.bvh_shape_count_enabled),
        }
    finally:
        cams.hide(hidden)
    return out


def _rates(env, ceiling_graph, config, steps: int) -> dict[str, float]:
    """Env-steps/s of the env step with the cameras' render as captured now, and of the ceiling rendered with
    ``config`` (``None``: the env's settings)."""
    step_graph, render_graph = env.sim.step_graph, env.sensors.cameras.render_graph
    with wp.ScopedDevice(env.device):
        ceiling = ceiling_graph(config)

    def env_with_camera():
        wp.capture_launch(step_graph)
        wp.capture_launch(render_graph)

    t_cam = _time_graph(env_with_camera, steps, env.device)
    t_ceiling = _time_graph(lambda: wp.capture_launch(ceiling), steps, env.device)
    return {"env_steps_per_s_with_camera": env.num_envs / t_cam, "ceiling_env_steps_per_s": env.num_envs / t_ceiling}


def _setting_name(order, tile) -> str:
    return order.name if tile is None else f"{order.name}_{tile[0]}x{tile[1]}"


_ORDERS = SensorCamera.RenderOrder
RENDER_SWEEP = (
    *[(order, None, block) for order in (_ORDERS.PIXEL_PRIORITY, _ORDERS.VIEW_PRIORITY) for block in (64, 128)],
    *[(_ORDERS.TILED, tile, block) for tile in ((16, 8), (8, 8), (32, 4), (16, 4), (8, 4)) for block in (64, 128)],
)
"""(order, tile (w, h) [px] of the tiled order, threads per block) that ``bench --render-orders`` times."""


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


from .bench_collect import bench_collect, bench_collect_on_workers  # noqa: E402,F401 - re-exported (the CLI)
