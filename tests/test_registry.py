"""Every registered task builds, steps and resets (loop over the registry, as mjlab does)."""

from __future__ import annotations

import pytest
import torch

from newton_lab.registry import list_tasks, lookup


def test_import_has_no_side_effects():
    import subprocess
    import sys

    code = "import sys, newton_lab; assert 'warp' not in sys.modules and 'newton_lab.tasks' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_registry_lists_the_tasks():
    assert {"GalbotG1-PickCube-v0", "GalbotG1-StackCube-v0", "GalbotG1-Reach-v0"} <= set(list_tasks())
    with pytest.raises(ValueError):
        from newton_lab.registry import register

        register("GalbotG1-PickCube-v0", cfg=lookup("GalbotG1-PickCube-v0")["cfg"])


@pytest.mark.parametrize("task_id", ["GalbotG1-PickCube-v0", "GalbotG1-StackCube-v0", "GalbotG1-Reach-v0"])
def test_every_task_steps(task_id):
    from newton_lab.agents import ZeroAgent
    from newton_lab.envs import make_env

    env = make_env(task_id, num_envs=1, device="cpu", randomize=True)
    obs, reward, term, trunc, info = env.step(ZeroAgent().act(env))
    assert obs.shape == (1, env.obs_dim) and torch.isfinite(obs).all() and torch.isfinite(reward).all()
    assert not (term | trunc).any()
    assert env.action_dim == len(env.action_joint_names)
    assert sum(s.stop - s.start for s in env.obs_terms.values()) == env.obs_dim
