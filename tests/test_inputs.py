"""Bad input gets a one-line error naming the problem and the fix; nothing on disk is touched."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import torch

from newton_lab.envs import make_env


def _one_line(exc: BaseException) -> str:
    msg = str(exc.args[0]) if exc.args else str(exc)
    assert "\n" not in msg, msg
    return msg


def test_unknown_task_lists_valid_ids():
    with pytest.raises(ValueError) as e:
        make_env("GalbotG1-Nope-v0")
    msg = _one_line(e.value)
    assert "GalbotG1-PickCube-v0" in msg and "GalbotG1-StackCube-v0" in msg and "GalbotG1-Reach-v0" in msg


@pytest.mark.parametrize("n", [0, -3, 1.5, "2"])
def test_num_envs_must_be_positive_int(n):
    with pytest.raises(ValueError) as e:
        make_env("GalbotG1-PickCube-v0", num_envs=n)
    assert "num_envs" in _one_line(e.value)


def test_unknown_task_option():
    with pytest.raises(ValueError) as e:
        make_env("GalbotG1-PickCube-v0", task_options={"sorting_object": "red_cube"})
    msg = _one_line(e.value)
    assert "sorting_object" in msg and "valid options" in msg


def test_wrong_action_shape(pick_env):
    with pytest.raises(ValueError) as e:
        pick_env.step(torch.zeros(pick_env.num_envs, pick_env.action_dim + 1))
    msg = _one_line(e.value)
    assert "(2, 8)" in msg and "left_arm_joint1" in msg


def test_wrong_action_dtype(pick_env):
    with pytest.raises(ValueError) as e:
        pick_env.step(torch.zeros(2, 8, dtype=torch.float64))
    assert "float32" in _one_line(e.value)


def test_wrong_action_device(pick_env):
    with pytest.raises(ValueError) as e:
        pick_env.step(torch.zeros(2, 8, device="meta"))
    msg = _one_line(e.value)
    assert "meta" in msg and ".to(" in msg


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_actions(pick_env, bad):
    a = pick_env.current_action()
    a[1, 3] = bad
    with pytest.raises(ValueError) as e:
        pick_env.step(a)
    assert "rows [1]" in _one_line(e.value)


def test_actions_must_be_tensors(pick_env):
    with pytest.raises(ValueError) as e:
        pick_env.step(np.zeros((2, 8), dtype=np.float32))
    assert "torch.as_tensor" in _one_line(e.value)


def test_reset_rows_out_of_range(pick_env):
    with pytest.raises(ValueError) as e:
        pick_env.reset([0, 5])
    assert "[0, 2)" in _one_line(e.value)


@pytest.mark.parametrize("ids", [torch.tensor([0.5]), torch.tensor([True, False]), np.array([1.0])])
def test_reset_rows_must_be_integers(pick_env, ids):
    with pytest.raises(ValueError) as e:
        pick_env.reset(ids)
    assert "integer row indices" in _one_line(e.value)


def test_planner_for_unknown_task():
    from newton_lab.agents import PlannerAgent

    with pytest.raises(ValueError):
        PlannerAgent.from_task("GalbotG1-Nope-v0")


def test_collect_into_missing_parent(pick_env, tmp_path):
    """The Python API creates a dataset's missing folders, as the command line does; a file in the way of one is
    refused in one line and nothing is written."""
    from newton_lab.agents import ZeroAgent

    target = tmp_path / "missing" / "deeper" / "demos.hdf5"
    ref = pick_env.collect(agent=ZeroAgent(), episodes=1, path=target, max_steps=2, progress=False)
    assert target.is_file() and ref["episodes"] == 1
    (tmp_path / "afile").write_text("keep")
    with pytest.raises(ValueError) as e:
        pick_env.collect(agent=ZeroAgent(), episodes=1, path=tmp_path / "afile" / "x.hdf5", max_steps=2, progress=False)
    assert "is a file" in _one_line(e.value) and (tmp_path / "afile").read_text() == "keep"


def test_collect_refuses_dataset_of_another_task(pick_env, tmp_path):
    from newton_lab.agents import ZeroAgent
    from newton_lab.datasets import open_writer

    path = tmp_path / "stack.hdf5"
    with open_writer(path, task_id="GalbotG1-StackCube-v0", env_args={}) as w:
        w.append_episode({"actions": np.zeros((3, 8), np.float32)}, success=True)
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    with pytest.raises(ValueError) as e:
        pick_env.collect(agent=ZeroAgent(), episodes=1, path=path, max_steps=2, progress=False)
    msg = _one_line(e.value)
    assert "GalbotG1-StackCube-v0" in msg and "GalbotG1-PickCube-v0" in msg
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before


def test_collect_bad_suffix_and_counts(pick_env, tmp_path):
    from newton_lab.agents import ZeroAgent

    with pytest.raises(ValueError) as e:
        pick_env.collect(agent=ZeroAgent(), episodes=1, path=tmp_path / "demos.csv", max_steps=2, progress=False)
    assert ".hdf5" in _one_line(e.value)
    with pytest.raises(ValueError) as e:
        pick_env.evaluate(agent=ZeroAgent(), episodes=0, max_steps=2, progress=False)
    assert "episodes" in _one_line(e.value)
