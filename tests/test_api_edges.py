"""The API's edges answer in the project's one-line form: rows named by something that is no row index, collect
without an agent or a path, an env from an unresolved TaskCfg; and a step with actions that require grad leaves the
env's action buffer out of the autograd graph."""

from __future__ import annotations

import pytest
import torch

TASK = "GalbotG1-Reach-v0"


@pytest.fixture(scope="module")
def env():
    from newton_lab.envs import make_env

    return make_env(TASK, num_envs=2, device="cpu", cameras=False)


@pytest.mark.parametrize("ids", ["rows", [None], {"a": 1}, object()])
def test_reset_with_something_that_is_no_row_index_is_one_line(env, ids):
    with pytest.raises(ValueError, match="env_ids must be None .every row. or integer row indices") as err:
        env.reset(ids)
    assert "\n" not in str(err.value)


def test_collect_without_an_agent_or_a_path_is_one_line_and_writes_nothing(env, tmp_path):
    from newton_lab.agents import expert_agent

    with pytest.raises(
        ValueError,
        match="agent NoneType lacks .'act', 'reset', 'done', 'holding'.; subclass newton_lab.agents.BaseAgent",
    ):
        env.collect(agent=None, episodes=1, path=tmp_path / "x.hdf5", progress=False)
    with pytest.raises(ValueError, match="path must name the dataset to write"):
        env.collect(agent=expert_agent(env), episodes=1, path=None, progress=False)
    with pytest.raises(ValueError, match="subclass newton_lab.agents.BaseAgent"):
        env.evaluate(agent=None, episodes=1, progress=False)
    assert not list(tmp_path.iterdir())


def test_an_agent_with_act_alone_is_refused_before_the_rollout_names_base_agent(env):
    """A rollout calls the agent's hooks (``reset``, ``done``, ``holding``, ``done_reason``) without probing for
    them: an object with ``act`` alone is refused in one line that names the template to subclass."""

    class ActOnly:
        def act(self, env, env_ids=None):
            return env.current_action()

    with pytest.raises(
        ValueError,
        match=r"agent ActOnly lacks \['reset', 'done', 'holding'\]; subclass "
        r"newton_lab.agents.BaseAgent",
    ) as err:
        env.evaluate(agent=ActOnly(), episodes=1, progress=False)
    assert "\n" not in str(err.value)


def test_an_env_from_an_unresolved_cfg_names_make_cfg():
    import newton_lab.tasks  # noqa: F401

    from newton_lab.envs.env import NewtonEnv
    from newton_lab.task_api.registry import lookup

    with pytest.raises(ValueError, match=r"TaskSpec.make_cfg\(options\)"):
        NewtonEnv(lookup("GalbotG1-PickCube-v0").cfg(), num_envs=1, device="cpu")


def test_actions_that_require_grad_leave_the_env_out_of_the_graph(env):
    actions = env.current_action().clone().requires_grad_(True)
    env.step(actions * 1.0)
    env.step(actions * 1.0)
    assert not env.buffers.actions.requires_grad and env.buffers.actions.grad_fn is None
    assert env.buffers.actions.cpu().numpy().shape == (2, env.action_dim)


def test_a_read_only_zarr_dataset_is_called_read_only_not_damaged(tmp_path, monkeypatch):
    """Appending to a zarr dataset its user may read but not write (permission denied, a read-only mount; simulated:
    the test runs as root) says so, not that the dataset is damaged; nothing is written."""
    import errno
    import os

    from test_lerobot_export import ENV_ARGS, TASK, make_dataset, make_episode

    from newton_lab.datasets import open_writer, read_dataset_info
    from newton_lab.datasets.zarr import session as zarr_session

    path = make_dataset(tmp_path / "d.zarr")
    real_open = os.open

    def read_only(file, flags, *args, **kwargs):
        if str(file).endswith("zarr.json") and flags & (os.O_RDWR | os.O_WRONLY):
            raise PermissionError(errno.EACCES, "Permission denied", str(file))
        return real_open(file, flags, *args, **kwargs)

    monkeypatch.setattr(zarr_session.os, "open", read_only)
    with pytest.raises(ValueError, match=r"d.zarr is read-only here \(Permission denied\); it was left untouched"):
        with open_writer(path, task_id=TASK, env_args=ENV_ARGS) as w:
            w.append_episode(make_episode(9, 5), success=True)
    monkeypatch.undo()
    assert read_dataset_info(path)["num_demos"] == 3


@pytest.mark.parametrize("seed", [2**31, -1, 10**30, 1.5, True])
def test_a_seed_outside_what_the_kernels_take_is_refused_before_the_build(seed, tmp_path):
    """Warp's reset kernels take 32-bit seeds and HDF5 stores the seed as an integer: a seed outside [0, 2**31 - 1]
    is refused when the env is made (it used to fail in the first write, after the dataset file was made)."""
    from newton_lab.envs import make_env

    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2147483647\]"):
        make_env(TASK, num_envs=1, device="cpu", cameras=False, seed=seed)


def test_reseed_takes_the_same_range(env):
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2147483647\], got -3"):
        env.reseed(-3)


def test_stack_cube_reference_rewards_opted_in_after_make_cfg_resolve_in_the_env():
    """The opt-in that StackCube's ``reference_rewards`` documents (``dataclasses.replace(cfg, rewards=...)`` on a
    ``make_cfg`` result) builds an env: the env resolves the new terms, their counters after the resolved ones'."""
    import dataclasses

    from newton_lab.tasks.stack_cube.mdp.rewards import reference_rewards

    from newton_lab.envs.env import NewtonEnv
    from newton_lab.task_api.registry import lookup
    from newton_lab.task_api.terms import unresolved_terms

    made = lookup("GalbotG1-StackCube-v0").make_cfg()
    cfg = dataclasses.replace(made, rewards=reference_rewards())
    generic = ["rewards.cube_2_on_cube_1", "rewards.cube_3_on_cube_2", "rewards.stack_success"]
    assert unresolved_terms(cfg) == generic  # action_rate is a plain @wp.func
    env = NewtonEnv(cfg, num_envs=1, device="cpu", cameras=False)
    assert not unresolved_terms(env.cfg) and env.cfg.hold_slots >= made.hold_slots
    _, reward, *_ = env.step(env.current_action())
    assert torch.isfinite(reward).all() and -0.01 <= float(reward[0]) <= 24.0
