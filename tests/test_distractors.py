"""Distractor objects (``tasks.common.distractors``) and the ``distractors`` perturbation axis, on real Newton models:
they come after the task's objects (every slot, observation and action of the task unchanged), every reset puts them
on the table clear of the task's objects and of each other, at new spots each episode, they stay there; an
evaluation builds an env for each count it asks for, and refuses one on an env built without it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from newton_lab.tasks.common.distractors import DISTRACTORS, distractor_count, with_distractors

from newton_lab.agents import expert_agent, perturbation_table
from newton_lab.envs import make_env
from newton_lab.task_api.perturbations import AXES, parse_cells
from newton_lab.task_api.registry import lookup

TASK = "GalbotG1-PickCube-v0"
GAP = 0.03
"""``scatter_on``'s clearance [m]."""


@pytest.fixture(scope="module")
def cluttered():
    return make_env(TASK, num_envs=2, device="cpu", seed=0, randomize=True, cameras=False, distractors=3)


def _centres(env) -> dict[str, np.ndarray]:
    """(rows, 3) centre of every entity [m]: a dynamic one's body, a static one's fixed pose."""
    q = env.state.body_q.numpy().reshape(env.num_envs, -1, 7)
    out = {}
    for e in env.cfg.entities:
        body = env.task.entities[e.name].body
        out[e.name] = q[:, body, :3] if body >= 0 else np.tile(np.array(e.pos), (env.num_envs, 1))
    return out


def _footprint(e) -> float:
    return float(np.hypot(*e.size[:2]) / 2)


def test_with_distractors_appends_objects_and_their_events_and_refuses_bad_counts():
    cfg = lookup(TASK).make_cfg({})
    more = with_distractors(cfg, 2)
    assert [e.name for e in more.entities] == [*(e.name for e in cfg.entities), "distractor_0", "distractor_1"]
    assert list(more.events)[: len(cfg.events)] == list(cfg.events)
    assert list(more.events)[len(cfg.events) :] == ["place_distractor_0", "place_distractor_1"]
    assert distractor_count(more) == 2 and distractor_count(cfg) == 0 and with_distractors(cfg, 0) is cfg
    for bad in (4, -1, 1.0, True):
        with pytest.raises(ValueError, match="whole number from 0 to 3"):
            with_distractors(cfg, bad)
    tableless = dataclasses.replace(cfg, entities=[e for e in cfg.entities if e.name != "table"])
    with pytest.raises(ValueError, match="no static 'table'"):
        with_distractors(tableless, 1)


def test_the_axis_counts_objects_up_to_three():
    assert parse_cells("distractors=mild")[0].values == {"distractors": 1.0}
    assert parse_cells("distractors=strong")[0].values == {"distractors": 3.0}
    for bad, why in (("distractors=4", "goes up to 3"), ("distractors=1.5", "whole number")):
        with pytest.raises(ValueError, match=why) as err:
            parse_cells(bad)
        assert "\n" not in str(err.value)
    assert AXES["distractors"].acts_on == "scene"


def test_the_task_is_unchanged_but_for_the_objects(cluttered, pick_env):
    assert cluttered.task.obs_dim == pick_env.task.obs_dim
    assert cluttered.action_dim == pick_env.action_dim
    plain = list(pick_env.task.entities)
    assert list(cluttered.task.entities)[: len(plain)] == plain
    assert all(cluttered.task.entities[n].slot == pick_env.task.entities[n].slot for n in plain)


def test_every_reset_puts_them_on_the_table_clear_of_the_rest_and_they_stay(cluttered):
    env, cfg = cluttered, cluttered.cfg
    table = next(e for e in cfg.entities if e.name == "table")
    top = table.pos[2] + table.size[2] / 2
    spots = []
    for seed in (0, 1):
        env.reseed(seed)
        for _ in range(30):  # settled: they stand where they were put
            env.step(env.current_action())
        c = _centres(env)
        for d in DISTRACTORS:
            p = c[d.name]
            assert np.all(np.abs(p[:, 0] - table.pos[0]) < table.size[0] / 2)
            assert np.all(np.abs(p[:, 1] - table.pos[1]) < table.size[1] / 2)
            np.testing.assert_allclose(p[:, 2], top + d.size[2] / 2, atol=3e-3)
            for e in cfg.entities:
                if e.name not in (d.name, "table") and np.all(np.abs(c[e.name][:, 2] - top) < 0.2):
                    gap = np.hypot(*(p[:, :2] - c[e.name][:, :2]).T) - _footprint(d) - _footprint(e)
                    assert np.all(gap > GAP - 5e-3), (d.name, e.name, gap)
        spots.append(np.stack([c[d.name] for d in DISTRACTORS]))
    assert not np.allclose(spots[0], spots[1])  # new spots each episode
    assert not np.allclose(spots[0][:, 0], spots[0][:, 1])  # and per row


def test_an_evaluation_builds_an_env_per_count_and_refuses_a_count_it_was_not_built_with(pick_env):
    built = []

    def rebuild(**scene):
        built.append(scene)
        env = make_env(TASK, num_envs=2, device="cpu", seed=0, randomize=True, cameras=False, **scene)
        return env, expert_agent(env)

    cells = parse_cells("distractors=mild") + parse_cells("object_mass=mild")
    rows = perturbation_table(
        pick_env, expert_agent(pick_env), cells, rebuild=rebuild, episodes=2, max_steps=5, progress=False
    )
    assert [r["perturbation"] for r in rows] == ["distractors=1", "object_mass=1.5"]
    assert built == [{"distractors": 1}] and all(r["episodes"] == 2 for r in rows)
    with pytest.raises(ValueError, match="built with 0; build it with") as err:
        perturbation_table(pick_env, expert_agent(pick_env), cells[:1], episodes=2, max_steps=5, progress=False)
    assert "\n" not in str(err.value)


def test_demos_collected_among_distractors_record_them_and_replay_in_their_scene(cluttered, tmp_path):
    """``collect --distractors N`` builds its env with them; the dataset records the count (``env_args``), and a
    replay (like Mimic) rebuilds that scene: the states hold the distractors' coordinates, and they replay."""
    from newton_lab.commands import CollectArgs
    from newton_lab.datasets import read_dataset_info, read_episode, state_tree
    from newton_lab.envs.recorder import recorded_scene
    from newton_lab.mimic import mimic
    from newton_lab.viz.rerun_log import replay_episode

    assert CollectArgs(distractors=2).env_kwargs()["distractors"] == 2
    assert CollectArgs().env_kwargs()["distractors"] == 0
    cluttered.reseed(0)
    ref = cluttered.collect(
        agent=expert_agent(cluttered), episodes=1, path=tmp_path / "d.hdf5", max_steps=400, only_successes=True
    )
    env_args = read_dataset_info(ref.path)["env_args"]
    assert env_args["env_kwargs"]["distractors"] == 3 and recorded_scene(env_args) == {"distractors": 3}
    assert recorded_scene({"env_kwargs": {}}) == {"distractors": 0}  # a dataset recorded before the count was
    ep = read_episode(ref.path, 0)
    poses = replay_episode(ref.path, 0, save=tmp_path / "replay.rrd")
    states = state_tree(ep["states"], env_args)
    for d in DISTRACTORS:
        body = cluttered.task.entities[d.name].body
        np.testing.assert_allclose(poses[:, body], states["rigid_object"][d.name]["root_pose"], atol=1e-5)
    generated = mimic(ref, episodes=1, num_envs=2, device="cpu", progress=False, max_attempts=6)
    assert generated.metadata["successes"] == 1  # Mimic's env stood among the same objects: its states hold theirs
    gen_args = read_dataset_info(generated.path)["env_args"]
    assert recorded_scene(gen_args) == {"distractors": 3}
    gen = read_episode(generated.path, read_dataset_info(generated.path)["demo_ids"][0])
    assert {d.name for d in DISTRACTORS} <= set(state_tree(gen["states"], gen_args)["rigid_object"])
