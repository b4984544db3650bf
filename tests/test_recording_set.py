"""A dataset's recording set is part of what it is: demos recorded with other cameras, another obs_mode or other task
options are not appended to it (refused in one line, the dataset unchanged); the same settings append."""

from __future__ import annotations

import pytest

TASK = "GalbotG1-Reach-v0"


def test_appending_demos_recorded_otherwise_is_refused(tmp_path):
    from newton_lab.agents import expert_agent
    from newton_lab.datasets import read_dataset_info
    from newton_lab.envs import make_env

    path = tmp_path / "r.hdf5"
    env = make_env(TASK, num_envs=1, device="cpu", cameras=False)
    env.collect(agent=expert_agent(env), episodes=1, path=path, max_steps=3, progress=False)
    size = path.stat().st_size
    sensors = make_env(TASK, num_envs=1, device="cpu", cameras=False, task_options={"obs_mode": "sensors"})
    with pytest.raises(
        ValueError,
        match=r"r.hdf5 was recorded with --obs-mode state, not sensors; append with "
        r"--obs-mode state, or collect into another path",
    ):
        sensors.collect(agent=expert_agent(sensors), episodes=1, path=path, max_steps=3, progress=False)
    cams = make_env(TASK, num_envs=1, device="cpu", cameras={"front_head": (16, 12)})
    with pytest.raises(
        ValueError,
        match=r"r.hdf5 was recorded with cameras none, not front_head=16x12:rgb; append "
        r"with --cameras none",
    ):
        cams.collect(agent=expert_agent(cams), episodes=1, path=path, max_steps=3, progress=False)
    assert path.stat().st_size == size and read_dataset_info(path)["num_demos"] == 1
    state = make_env(TASK, num_envs=1, device="cpu", cameras=False, task_options={"obs_mode": "state"})  # the default
    state.collect(agent=expert_agent(state), episodes=1, path=path, max_steps=3, progress=False)
    assert read_dataset_info(path)["num_demos"] == 2
