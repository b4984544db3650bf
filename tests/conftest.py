"""Shared fixtures: envs are built once per session (Warp compiles each kernel once and caches it)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session", autouse=True)
def _quiet_warp():
    import warp as wp

    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    yield


@pytest.fixture(scope="session")
def pick_env():
    from newton_lab.envs import make_env

    return make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=0, randomize=True, cameras=False)


@pytest.fixture(scope="session")
def stack_env():
    from newton_lab.envs import make_env

    return make_env("GalbotG1-StackCube-v0", num_envs=1, device="cpu", seed=3, randomize=True)


@pytest.fixture(scope="session")
def reach_env():
    from newton_lab.envs import make_env

    return make_env("GalbotG1-Reach-v0", num_envs=2, device="cpu", seed=0, randomize=True)


def run_until_done(env, agent, max_steps: int):
    """Step every row until each has finished one episode; returns per-row (success, reason, length)
    and the per-step history of the env's entity poses and signals."""
    import numpy as np
    import torch

    env.reset()
    agent.reset()
    result = [None] * env.num_envs
    poses, signals = [], []
    for _ in range(max_steps):
        _, _, term, trunc, info = env.step(agent.act(env))
        poses.append(env.entity_poses.clone())
        signals.append(info["signals"].clone())
        for row in np.nonzero((term | trunc).numpy())[0]:
            if result[row] is None:
                result[row] = (bool(info["success"][row]), env.termination_reasons[int(info["termination_reason"][row])],
                               int(info["episode_length"][row]))
        if all(r is not None for r in result):
            break
    return result, torch.stack(poses), torch.stack(signals)
