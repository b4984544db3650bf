"""Throughput of the full captured env step against the bare solver on the identical model.

Both are measured side by side in one process: the env's captured step (actions -> decimation solver
steps -> task kernel -> masked resets -> observations) and a graph of just ``decimation`` solver steps.
"""

from __future__ import annotations

import time
from typing import Any

import torch
import warp as wp


def _time_graph(launch, steps: int, device) -> float:
    for _ in range(3):
        launch()
    wp.synchronize_device(device)
    t0 = time.perf_counter()
    for _ in range(steps):
        launch()
    wp.synchronize_device(device)
    return (time.perf_counter() - t0) / steps


def bench(task_id: str, *, num_envs: int = 4, steps: int = 200, device: str | None = None) -> dict[str, Any]:
    """Env-steps/s, bare world-steps/s and their per-step time ratio (env step / decimation solver steps)."""
    from .envs import make_env

    env = make_env(task_id, num_envs=num_envs, device=device, seed=0)
    if env._graph is None:
        raise RuntimeError(f"step capture is unavailable on {env.device}; benchmark needs Warp graph capture")
    env.actions.copy_(env.current_action())
    with wp.ScopedDevice(env.device):
        with wp.ScopedCapture(device=env.device) as cap:
            env._simulate()
    bare_graph = cap.graph
    t_env = _time_graph(lambda: wp.capture_launch(env._graph), steps, env.device)
    t_bare = _time_graph(lambda: wp.capture_launch(bare_graph), steps, env.device)
    # the Python-facing step (validation + copy + launch) on the same env
    a = env.current_action()
    t_api = _time_graph(lambda: env.step(a), max(steps // 4, 1), env.device)
    dec = env.cfg.decimation
    return {
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
