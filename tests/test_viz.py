"""rerun recordings open with rerun's reader; replaying a dataset episode reproduces its recorded states."""

from __future__ import annotations

import re

import numpy as np
import pytest

from newton_lab.agents import PlannerAgent
from newton_lab.datasets import read_episode
from newton_lab.viz import RerunLogger, replay_episode


def _entities(rrd) -> dict[str, int]:
    from rerun.chunk import RrdReader

    rows = {}
    for line in str(RrdReader(str(rrd)).store().summary()).splitlines():
        m = re.match(r"(\S+) rows=(\d+)", line.strip())
        if m:
            rows[m.group(1)] = rows.get(m.group(1), 0) + int(m.group(2))
    return rows


def test_recording_has_bodies_shapes_and_scalars(pick_env, tmp_path):
    rrd = tmp_path / "run.rrd"
    logger = RerunLogger(pick_env, save=rrd, max_worlds=1)
    agent = PlannerAgent.from_task(pick_env.task_id)
    pick_env.reset()
    agent.reset()
    for _ in range(6):
        _, reward, _, _, info = pick_env.step(agent.act(pick_env))
        logger.log_step(reward=reward, success=info["success"])
    logger.close()
    rows = _entities(rrd)
    assert rows["/metrics/0/reward"] == 6 and rows["/metrics/0/phase"] == 6 and rows["/world/0/tcp"] == 6
    assert rows["/world/0/cube"] == 6 and rows["/world/0/left_arm_link7"] == 6
    assert any(k.startswith("/world/0/cube/shape_") for k in rows)
    assert not any(k.startswith("/world/1/") for k in rows)  # only the first max_worlds rows are drawn


def test_view_replays_recorded_states(pick_env, tmp_path):
    ref = pick_env.collect(agent=PlannerAgent.from_task(pick_env.task_id), episodes=1, path=tmp_path / "d.hdf5",
                           max_steps=400, progress=False)
    rrd = tmp_path / "replay.rrd"
    poses = replay_episode(ref.path, 0, save=rrd)
    ep = read_episode(ref.path, 0)
    cube = pick_env.entities["cube"].body
    np.testing.assert_allclose(poses[:, cube], ep["states"]["rigid_object"]["cube"]["root_pose"], atol=1e-5)
    # the replayed TCP follows the recorded one (forward kinematics of the recorded joints)
    assert _entities(rrd)["/world/0/cube"] == ep["attrs"]["num_samples"]
    with pytest.raises(ValueError) as e:
        replay_episode(ref.path, 7)
    assert "no episode 7" in str(e.value)
