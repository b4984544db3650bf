"""The task option ``obs_mode="sensors"``: envs and datasets without object or target poses, observing only what a
real robot measures (proprioception and cameras)."""

from __future__ import annotations

import newton
import newton_lab.tasks  # noqa: F401  (registers every task id)
import pytest
import torch
import warp as wp

from newton_lab.envs import make_env
from newton_lab.task_api.registry import list_tasks, lookup

POSE_TERMS = {
    "cube_pose",
    "blue_block_pos",
    "bar_pose",
    "object_pose",
    "cube_positions",
    "cube_orientations",
    "goal_pos",
    "pose_command",
}
"""Every observation term of today's tasks that reads a scene object's pose or a target's position."""


@pytest.mark.parametrize("task_id", list_tasks())
def test_sensors_mode_removes_every_pose_term(task_id):
    spec = lookup(task_id)
    state, sensors = spec.make_cfg(), spec.make_cfg({"obs_mode": "sensors"})
    assert not any(t.privileged for t in sensors.observations.values())
    assert set(sensors.observations) == {k for k, t in state.observations.items() if not t.privileged}
    assert not set(sensors.observations) & POSE_TERMS, task_id
    assert sensors.options["obs_mode"] == "sensors" and sensors.cameras == state.cameras


def test_sensors_observation_does_not_see_the_cube():
    """Teleporting the cube changes the state-mode observation but not the sensors-mode one (cameras off)."""
    seen = {}
    for mode in ("state", "sensors"):
        env = make_env("GalbotG1-PickCube-v0", num_envs=1, device="cpu", task_options={"obs_mode": mode}, cameras=False)
        obs, _ = env.reset()
        before = obs.clone()
        c = env.task.entities["cube"].coord
        q = wp.to_torch(env.state.joint_q).view(1, -1)
        q[0, c : c + 3] += torch.tensor([0.05, -0.04, 0.0])
        newton.eval_fk(env.model, env.state.joint_q, env.state.joint_qd, env.state)
        env.sim.observe()
        seen[mode] = bool((env.obs - before).abs().max() > 1e-6)
        assert "cube_pose" in env.task.obs_terms if mode == "state" else "cube_pose" not in env.task.obs_terms
    assert seen == {"state": True, "sensors": False}


def test_unknown_obs_mode_is_one_line():
    with pytest.raises(ValueError, match=r"unknown obs_mode 'pixels'; valid values: \['state', 'sensors'\]"):
        lookup("GalbotG1-PickCube-v0").make_cfg({"obs_mode": "pixels"})


def test_task_options_as_keywords():
    env = make_env("GalbotG1-PickCube-v0", device="cpu", obs_mode="sensors", cameras=False)
    assert env.cfg.options == {"obs_mode": "sensors"} and "cube_pose" not in env.task.obs_terms
    with pytest.raises(ValueError, match="unknown task option"):
        make_env("GalbotG1-PickCube-v0", device="cpu", sorting_object="red_cube")
    with pytest.raises(ValueError, match="given twice"):
        make_env("GalbotG1-PickCube-v0", device="cpu", task_options={"obs_mode": "state"}, obs_mode="sensors")
