"""Every registered task builds, steps and resets (loop over the registry, as mjlab does)."""

from __future__ import annotations

import dataclasses

import newton_lab.tasks  # noqa: F401  (registers every task id)
import pytest
import torch

from newton_lab.task_api.registry import TaskSpec, list_tasks, lookup, register


def test_import_has_no_side_effects():
    import subprocess
    import sys

    code = "import sys, newton_lab; assert 'warp' not in sys.modules and 'newton_lab.tasks' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_registry_lists_the_tasks():
    assert {"GalbotG1-PickCube-v0", "GalbotG1-StackCube-v0", "GalbotG1-Reach-v0"} <= set(list_tasks())
    with pytest.raises(ValueError):
        register(dataclasses.replace(lookup("GalbotG1-PickCube-v0")))
    spec = lookup("GalbotG1-PickCube-v0")
    assert isinstance(spec, TaskSpec) and spec.expert is not None and spec.description
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.description = "changed"  # type: ignore[misc]


@pytest.mark.parametrize("task_id", list_tasks())
def test_every_task_steps(task_id):
    from newton_lab.agents import ZeroAgent
    from newton_lab.envs import make_env

    env = make_env(task_id, num_envs=1, device="cpu", randomize=True)
    obs, reward, term, trunc, info = env.step(ZeroAgent().act(env))
    assert obs.shape == (1, env.task.obs_dim) and torch.isfinite(obs).all() and torch.isfinite(reward).all()
    assert not (term | trunc).any()
    assert env.action_dim == len(env.action_joint_names)
    assert sum(s.stop - s.start for s in env.task.obs_terms.values()) == env.task.obs_dim
    count = int(env.buffers.episode_count[0])
    obs, _ = env.reset()
    assert torch.isfinite(obs).all() and int(env.buffers.episode_count[0]) == count + 1, "reset starts a new episode"
