"""gymnasium adapter (newton_lab.envs.gym) on real CPU physics: registered ids, spaces, same-step auto-reset with
final_obs / final_info, seeded resets, partial resets, gymnasium's own env checker."""

from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import newton_lab.envs.gym as ngym
from newton_lab.envs import NewtonEnv
from newton_lab.task_api.registry import list_tasks, lookup

TASK = "GalbotG1-PickCube-v0"
GYM_ID = f"newton_lab/{TASK}"


@pytest.fixture(scope="module")
def vec():
    envs = gymnasium.make_vec(GYM_ID, num_envs=2, device="cpu", seed=0, randomize=True)
    yield envs
    envs.close()


@pytest.fixture(scope="module")
def short_vec():
    """Two rows of PickCube whose episodes are cut at 3 steps (every row auto-resets on step 3)."""
    base = lookup(TASK).make_cfg()
    cfg = dataclasses.replace(base, episode_length_s=3 * base.control_dt)
    return ngym.NewtonVectorEnv(env=NewtonEnv(cfg, num_envs=2, device="cpu", seed=0))


def test_every_task_is_registered():
    assert sorted(ngym.GYM_IDS) == [f"newton_lab/{t}" for t in list_tasks()]
    assert all(i in gymnasium.registry for i in ngym.GYM_IDS)


def test_make_vec_gives_one_batched_env_with_spaces(vec):
    env = vec.unwrapped.env
    assert isinstance(vec.unwrapped, ngym.NewtonVectorEnv) and vec.num_envs == 2 and env.num_envs == 2
    assert vec.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    single = vec.single_observation_space
    images = list(env.sensors.image_terms)
    assert list(single.keys()) == list(env.task.obs_terms) + images
    assert sum(single[k].shape[0] for k in env.task.obs_terms) == env.task.obs_dim
    assert all(vec.observation_space[k].shape == (2, *single[k].shape) for k in single)
    act = vec.single_action_space
    assert act.shape == (env.action_dim,) and vec.action_space.shape == (2, env.action_dim)
    assert np.isfinite(act.low).all() and np.isfinite(act.high).all() and (act.low < act.high).all()
    grip = env.action_joint_names.index(env.action_joint_names[env.joints.binding.actions.kinds.index("binary")])
    assert act.low[grip] == pytest.approx(0.0) and act.high[grip] == pytest.approx(1.2)


def test_reset_and_step_stay_in_the_spaces(vec):
    obs, info = vec.reset(seed=3)
    assert vec.observation_space.contains(obs)
    vec.action_space.seed(0)
    for _ in range(2):
        obs, reward, terminated, truncated, info = vec.step(vec.action_space.sample())
        assert vec.observation_space.contains(obs)
        assert reward.shape == (2,) and terminated.dtype == np.bool_ and truncated.dtype == np.bool_
        assert info["episode_length"].tolist() == [info["episode_length"][0]] * 2 and info["_success"].all()


def test_seeded_reset_reproduces_and_seeds_differ(vec):
    first, _ = vec.reset(seed=5)
    vec.step(np.zeros(vec.action_space.shape, np.float32))
    again, _ = vec.reset(seed=5)
    other, _ = vec.reset(seed=6)
    np.testing.assert_array_equal(first["cube_pose"], again["cube_pose"])
    assert not np.allclose(first["cube_pose"], other["cube_pose"])
    assert not np.allclose(first["cube_pose"][0], first["cube_pose"][1])  # each row draws its own stream
    with pytest.raises(ValueError, match="seed must be one int"):
        vec.reset(seed=[1, 2])


def test_reset_mask_resets_only_the_masked_rows(vec):
    vec.reset(seed=1)
    moved, *_ = vec.step(np.zeros(vec.action_space.shape, np.float32))
    obs, _ = vec.reset(options={"reset_mask": np.array([True, False])})
    np.testing.assert_array_equal(obs["robot_joint_pos"][1], moved["robot_joint_pos"][1])
    assert not np.allclose(obs["robot_joint_pos"][0], moved["robot_joint_pos"][0])
    with pytest.raises(ValueError, match=r"reset_mask'\] must be a \(2,\) bool array"):
        vec.reset(options={"reset_mask": [1, 0]})


def test_auto_reset_rows_carry_final_obs_and_final_info(short_vec):
    first, _ = short_vec.reset()
    hold = np.zeros(short_vec.action_space.shape, np.float32)
    for step in range(3):
        obs, reward, terminated, truncated, info = short_vec.step(hold)
        if step < 2:
            assert "final_obs" not in info and not (terminated | truncated).any()
    assert truncated.all() and info["_final_obs"].all() and info["_final_info"].all()
    assert info["final_info"]["episode_length"].tolist() == [3, 3]
    assert (info["final_info"]["termination_reason"] == short_vec.termination_reasons.index("time_out")).all()
    state_terms = short_vec.env.task.obs_terms
    state_space = gymnasium.spaces.Dict({k: short_vec.single_observation_space[k] for k in state_terms})
    for row in range(2):
        final = info["final_obs"][row]
        assert state_space.contains(final)  # the state terms (camera images show the current state only)
        # the returned obs is the new episode's first one (the default reset, no randomisation) ...
        np.testing.assert_array_equal(obs["robot_joint_pos"][row], first["robot_joint_pos"][row])
        # ... and final_obs the state the third step reached
        assert not np.allclose(final["robot_joint_pos"], first["robot_joint_pos"][row])


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:.*(symmetric and normalized|infinity):UserWarning")
def test_make_gives_one_world_that_passes_gymnasiums_checker():
    env = gymnasium.make(GYM_ID, device="cpu")
    assert env.unwrapped.vector.env.num_envs == 1
    check_env(env.unwrapped, skip_render_check=True)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs) and isinstance(reward, float) and set(info) == set(ngym.INFO_KEYS)
    with pytest.raises(ValueError, match=r"use gymnasium.make_vec\('newton_lab/GalbotG1-PickCube-v0', num_envs=3\)"):
        gymnasium.make(GYM_ID, num_envs=3, device="cpu")
