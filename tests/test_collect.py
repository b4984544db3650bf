"""Collection into HDF5 and zarr on real physics; a SIGKILLed collection keeps every finished episode."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from newton_lab.agents import PlannerAgent, ZeroAgent
from newton_lab.datasets import read_dataset_info, read_episode, state_tree
from newton_lab.datasets.zarr.nodes import inodes_of


@pytest.mark.parametrize("suffix", [".hdf5", ".zarr"])
def test_collect_writes_the_robomimic_layout(pick_env, tmp_path, suffix):
    path = tmp_path / f"demos{suffix}"
    summary = pick_env.collect(
        agent=PlannerAgent.from_task(pick_env.task_id), episodes=3, path=path, max_steps=400, progress=False
    )
    assert summary["episodes"] == 3 and summary["successes"] == 3 and summary["success_rate"] == 1.0
    assert summary["termination_reasons"] == {"success": 3} and len(summary["saved_demo_ids"]) == 3
    assert summary["subtask_signals"] == {"grasped_cube": 3}  # every expert episode grasped the cube
    info = read_dataset_info(path)
    assert info["task_id"] == "GalbotG1-PickCube-v0" and info["num_demos"] == 3
    assert info["env_args"]["env_name"] == "GalbotG1-PickCube-v0"
    assert info["env_args"]["newton_lab"]["action_joint_names"][-1] == "left_gripper_joint"
    assert info["total"] == sum(summary["episode_lengths"])
    ep = read_episode(path, summary["saved_demo_ids"][0])
    t = ep["attrs"]["num_samples"]
    assert ep["attrs"]["success"] and ep["attrs"]["termination_reason"] == "success"
    assert ep["actions"].shape == (t, 8) and ep["actions"].dtype == np.float32
    for term, sl in pick_env.task.obs_terms.items():
        assert ep["obs"][term].shape == (t, sl.stop - sl.start)
    states = state_tree(ep["states"], info["env_args"])  # flat (T, D) states, named by env_args
    layout = info["env_args"]["newton_lab"]["state_layout"]
    assert ep["states"].shape == (t, layout["joint_qd"][1]) and ep["states"].dtype == np.float32
    robot = states["articulation"]["robot"]
    assert robot["joint_position"].shape == (t, 34)
    np.testing.assert_array_equal(ep["initial_state"], ep["states"][:1])
    assert ep["rewards"].shape == (t,) and ep["rewards"].dtype == np.float32
    np.testing.assert_allclose(ep["rewards"].sum(), summary["reward_totals"][0], rtol=1e-4, atol=1e-4)
    assert ep["dones"].tolist() == [0] * (t - 1) + [1]  # robomimic: 1 on the last step of a success
    for term in pick_env.task.obs_terms:  # next_obs: the observation after each step, the last one before the reset
        np.testing.assert_array_equal(ep["next_obs"][term][:-1], ep["obs"][term][1:])
    assert ep["next_obs"]["cube_pose"][-1, 2] > ep["obs"]["cube_pose"][0, 2] + 0.01  # lifted, not the reset pose
    cube = states["rigid_object"]["cube"]["root_pose"]
    np.testing.assert_allclose(cube, ep["datagen"]["object_poses"]["cube"], atol=1e-6)
    grasped = ep["datagen"]["subtask_signals"]["grasped_cube"]
    assert grasped.dtype == bool and grasped.any() and not grasped[0]
    # the recorded observation of the cube is the recorded state of the cube
    np.testing.assert_allclose(ep["obs"]["cube_pose"], cube, atol=1e-6)
    # appending to the same dataset continues the ids
    more = pick_env.collect(
        agent=PlannerAgent.from_task(pick_env.task_id), episodes=1, path=path, max_steps=400, progress=False
    )
    assert more["saved_demo_ids"] == [3] and read_dataset_info(path)["num_demos"] == 4


@pytest.mark.slow
def test_sigkill_mid_collection_keeps_finished_episodes(tmp_path):
    path = tmp_path / "killed.hdf5"
    cmd = [
        sys.executable,
        "-m",
        "newton_lab.cli",
        "collect",
        "--task",
        "GalbotG1-PickCube-v0",
        "--episodes",
        "200",
        "--num-envs",
        "1",
        "--randomize",
        "--device",
        "cpu",
        "--no-progress",
        "--cameras",
        "none",
        "--dataset-path",
        str(path),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seen = 0
    try:
        deadline = time.time() + 600
        while time.time() < deadline and proc.poll() is None:
            time.sleep(0.3)
            if path.exists():
                try:
                    seen = read_dataset_info(path)["num_demos"]
                except Exception:
                    continue
                if seen >= 3:
                    break
        assert seen >= 3, "collection did not write three episodes in time"
        time.sleep(0.45)  # land somewhere inside the next episode
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    info = read_dataset_info(path)
    assert info["num_demos"] >= seen
    for demo in info["demo_ids"]:
        ep = read_episode(path, demo)
        assert ep["actions"].shape[0] == ep["attrs"]["num_samples"] > 0
    assert json.dumps(info["env_args"])  # metadata intact


def test_collect_to_a_log_prints_progress_lines(pick_env, tmp_path, monkeypatch, capsys):
    """stderr not a terminal (a log file, Prefect): no tqdm bar, plain lines with the episodes ended so far."""
    monkeypatch.setattr("newton_lab.envs.rollout_loop.LOG_EVERY_S", 0.0)
    pick_env.collect(agent=ZeroAgent(), episodes=4, path=tmp_path / "log.hdf5", max_steps=2, progress=True)
    lines = [x for x in capsys.readouterr().err.splitlines() if x.startswith(f"{pick_env.task_id}: step ")]
    assert len(lines) >= 2 and "4 episodes ended, 0 successes" in lines[-1], lines


def test_collect_writes_episodes_that_end_together_as_one_batch(pick_env, tmp_path):
    """Both rows end at the step limit together: one device->host copy, one batch each time."""
    path = tmp_path / "batched.zarr"
    ref = pick_env.collect(agent=ZeroAgent(), episodes=4, path=path, max_steps=2, progress=False)
    assert ref["saved_demo_ids"] == [0, 1, 2, 3] and 1 <= ref["writer_batches"] <= 2
    info = read_dataset_info(path)
    assert info["demo_ids"] == [0, 1, 2, 3] and info["total"] == 8
    assert sorted(read_episode(path, i)["attrs"]["env_index"] for i in (0, 1)) == [0, 1]
    tree = {k: v for k, v in read_episode(path, 0).items() if k != "attrs"}
    assert inodes_of(tree) == sum(1 for _ in (path / "data" / "demo_0").rglob("*")) + 1  # the room check's count


def test_collect_refuses_a_zarr_run_the_inodes_cannot_hold(pick_env, tmp_path, monkeypatch):
    """Before anything is written: a zarr collection whose demos need more inodes than the filesystem has free
    is refused in one line with the numbers and the fix; HDF5 (one file) is not affected."""
    import newton_lab.datasets.zarr.inodes as room

    real = os.statvfs(tmp_path)
    free = type(
        "Stat",
        (),
        {"f_files": 10_000, "f_favail": 500, "f_ffree": 500, "f_bavail": real.f_bavail, "f_frsize": real.f_frsize},
    )
    monkeypatch.setattr(room.os, "statvfs", lambda p: free)
    path = tmp_path / "big.zarr"
    with pytest.raises(ValueError) as exc:
        pick_env.collect(agent=ZeroAgent(), episodes=20, path=path, max_steps=2, progress=False)
    line = str(exc.value)
    assert "20 zarr demos need at least" in line and "500 free" in line and "write .hdf5" in line
    assert "\n" not in line and not path.exists()
    ref = pick_env.collect(agent=ZeroAgent(), episodes=2, path=tmp_path / "small.hdf5", max_steps=2, progress=False)
    assert ref["saved_demo_ids"] == [0, 1]


@pytest.mark.parametrize("error", [KeyboardInterrupt, RuntimeError])
def test_interrupted_collect_still_writes_the_finished_episodes(pick_env, tmp_path, error):
    path = tmp_path / "interrupted.hdf5"
    steps = {"n": 0}

    def stop_after_five(reward, info):
        steps["n"] += 1
        if steps["n"] == 5:
            raise error("stop")

    with pytest.raises(error):
        pick_env.collect(
            agent=ZeroAgent(), episodes=20, path=path, max_steps=2, progress=False, on_step=stop_after_five
        )
    info = read_dataset_info(path)  # two steps of two rows ended twice before the interrupt
    assert info["demo_ids"] == [0, 1, 2, 3] and info["total"] == 8
    for demo in info["demo_ids"]:
        assert read_episode(path, demo)["actions"].shape == (2, 8)


def test_a_batch_of_episodes_fetched_at_once_equals_each_read_alone(pick_env):
    """``EpisodeRecorder.episodes`` copies the ended rows to the host in one go and splits the copy by array: every
    episode's arrays are those ``episode`` reads for its row alone, contiguous, and none is a view of the live
    buffers (the row's next episode overwrites them)."""
    from newton_lab.envs.recorder import EpisodeRecorder

    recorder = EpisodeRecorder(pick_env, 8)
    recorder._frames.uniform_()
    recorder._rewards.uniform_()
    recorder._next_obs.uniform_()
    trees, finite = recorder.episodes([1, 0], [5, 3])
    assert finite == {0: True, 1: True}

    def leaves(tree, prefix=""):
        for key, value in tree.items():
            yield from leaves(value, f"{prefix}{key}/") if isinstance(value, dict) else [(prefix + key, value)]

    for row, length in ((0, 3), (1, 5)):
        batch, alone = dict(leaves(trees[row])), dict(leaves(recorder.episode(row, length)))
        assert batch.keys() == alone.keys() and "next_obs/cube_pose" in batch and "obs/cube_pose" in batch
        for key, value in batch.items():
            assert value.shape[0] == (1 if key == "initial_state" else length), key
            assert np.array_equal(value, alone[key]) and value.flags.c_contiguous, key
    before = trees[1]["actions"].copy()
    recorder._frames.zero_()
    assert np.array_equal(trees[1]["actions"], before)  # host copies, not views of the recorder's buffers


def test_evaluate_times_the_env_step_and_the_agent(pick_env):
    """An evaluation says what the agent's act costs against the env step it drives (seconds, and milliseconds per
    vector step)."""
    from newton_lab.agents import ZeroAgent

    summary = pick_env.evaluate(agent=ZeroAgent(), episodes=2, max_steps=3, progress=False)
    t, steps = summary["timing"], summary["vector_steps"]
    assert steps == 3 and t["env_step_s"] > 0 and t["agent_s"] > 0
    assert t["env_step_ms_per_step"] == pytest.approx(1e3 * t["env_step_s"] / steps)
    assert t["agent_ms_per_step"] == pytest.approx(1e3 * t["agent_s"] / steps)
