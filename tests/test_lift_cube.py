"""GalbotG1-LiftCube-v0, added as nothing but its own package: registered, listed, solved by its expert."""

from __future__ import annotations

import subprocess
import sys

import torch
from conftest import run_until_done

from newton_lab.agents import expert_agent
from newton_lab.envs import make_env
from newton_lab.task_api.registry import list_tasks

TASK = "GalbotG1-LiftCube-v0"


def test_lift_cube_is_registered_and_listed():
    assert TASK in list_tasks()
    out = subprocess.run([sys.executable, "-m", "newton_lab.cli", "tasks"], capture_output=True, text=True, check=True)
    assert TASK in out.stdout


def test_lift_cube_expert_lifts_the_cube():
    env = make_env(TASK, num_envs=1, device="cpu", seed=2, randomize=True)
    start_z = float(env.buffers.entity_poses[0, env.task.entities["cube"].slot, 2])
    result, poses, signals = run_until_done(env, expert_agent(env), 400)
    assert result[0][:2] == (True, "success"), result
    z = poses[:, 0, env.task.entities["cube"].slot, 2]
    assert float(z.max()) >= start_z + 0.10
    assert bool((signals[:, 0, env.task.signal_names.index("grasped_cube")] > 0.5).any())


def test_lift_cube_needs_the_lift_not_just_the_grasp():
    env = make_env(TASK, num_envs=1, device="cpu", seed=0)
    env.reset()
    for _ in range(10):  # closing the gripper on nothing at the start posture lifts nothing
        a = env.current_action()
        a[:, env.action_joint_names.index("left_gripper_joint")] = 1.2
        _, _, term, trunc, info = env.step(a)
        assert not bool(info["success"][0]) and torch.isfinite(env.obs).all()
