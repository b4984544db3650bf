"""Shared fixtures: envs are built once per session (Warp compiles each kernel once and caches it)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

MODULE_SECONDS = {
    "test_crash_campaign.py": 540,
    "test_interrupts.py": 459,
    "test_interrupt_pipeline.py": 352,
    "test_experts.py": 296,
    "test_policy_vision.py": 287,
    "test_tutorial_chapters.py": 249,
    "test_flows_dask.py": 207,
    "test_examples.py": 183,
    "test_cli_inputs.py": 177,
    "test_readme.py": 169,
    "test_flows_long_horizon.py": 143,
    "test_rl.py": 132,
    "test_docs.py": 91,
    "test_suite.py": 85,
    "test_image_recording.py": 85,
    "test_policy.py": 78,
    "test_tutorial_simple_task.py": 68,
    "test_teleop_tmux.py": 67,
    "test_yolo_export.py": 50,
    "test_flows.py": 49,
    "test_env_perturbations.py": 44,
    "test_sort_to_shelf_all.py": 42,
    "test_physics_settings.py": 39,
    "test_run_records.py": 31,
    "test_perturbations.py": 31,
    "test_train_resume.py": 30,
    "test_mobile.py": 29,
    "test_registry.py": 28,
    "test_stage_processes.py": 27,
    "test_collect.py": 27,
    "test_docs_layout.py": 26,
    "test_warp_settings.py": 25,
    "test_env.py": 25,
    "test_cli.py": 22,
    "test_writer_process.py": 22,
    "test_data_parallel.py": 22,
    "test_rewards.py": 20,
    "test_yolo_train.py": 18,
    "test_architecture.py": 16,
    "test_teleop.py": 16,
}
"""Seconds each module of 15 s or more took in CI's ``make test`` (every test) on 2 CPU cores (warm Warp cache; the
junit report of ``pytest -n 2 --dist loadfile --junitxml=...`` summed per module). Modules run longest first, so the
two workers end together: xdist's own order (most tests first) left the four slowest modules to the end, one worker
running them while the other idled for about three minutes."""


def pytest_collection_modifyitems(config, items):
    """Longest modules first (``MODULE_SECONDS``; the rest after them, in their usual order). ``make test`` passes
    ``--no-loadscope-reorder`` so that xdist hands the modules out in this order."""
    items.sort(key=lambda item: -MODULE_SECONDS.get(Path(str(item.fspath)).name, 0))


def in_ci() -> bool:
    """Whether the suite runs in CI (``CI=true``, as CI services and ``.ci/run`` set it)."""
    return os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")


def missing_tool(what: str, module: bool = False) -> None:
    """A test's tool or package is not installed: skip it here, fail in CI (``in_ci``), where a skip would drop
    the test silently. ``module``: called at a test module's top level."""
    if in_ci():
        pytest.fail(f"{what}; CI must run this test (install it in the CI image)", pytrace=False)
    pytest.skip(what, allow_module_level=module)


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
    and the per-step history of the env's entity poses and signals. The env is reseeded first, so the rows run the
    episodes a fresh env runs, whatever ran on the shared fixture before."""
    import numpy as np
    import torch

    env.reseed(env.seed)
    agent.reset()
    result = [None] * env.num_envs
    poses, signals = [], []
    for _ in range(max_steps):
        _, _, term, trunc, info = env.step(agent.act(env))
        poses.append(env.buffers.entity_poses.clone())
        signals.append(info["signals"].clone())
        for row in np.nonzero((term | trunc).numpy())[0]:
            if result[row] is None:
                reason = env.task.termination_reasons[int(info["termination_reason"][row])]
                result[row] = (bool(info["success"][row]), reason, int(info["episode_length"][row]))
        if all(r is not None for r in result):
            break
    return result, torch.stack(poses), torch.stack(signals)
