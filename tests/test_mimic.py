"""Mimic: pose maths against hand-computed poses, and a real-physics generation run from 2 sources."""

from __future__ import annotations

import math

import numpy as np
import pytest

from newton_lab.datasets import DatasetRef, read_dataset_info, read_episode
from newton_lab.mimic import mimic, mimic_variant_of
from newton_lab.mimic.poses import (
    closest_symmetric_pose,
    interpolate_poses,
    mat_to_pose,
    pose_to_mat,
    transform_segment,
)


def _yaw_quat(a):
    return [0.0, 0.0, math.sin(a / 2), math.cos(a / 2)]


def test_pose_matrix_round_trip():
    p = np.array([0.1, -0.2, 0.3, *_yaw_quat(0.7)])
    np.testing.assert_allclose(mat_to_pose(pose_to_mat(p)), p, atol=1e-12)


def test_object_centric_transform_by_hand():
    # source: object at (1, 0, 0) yaw 0, eef 0.1 m above it; current: object at (0, 2, 0) yawed 90 deg
    src_obj = np.array([1.0, 0.0, 0.0, *_yaw_quat(0.0)])
    cur_obj = np.array([0.0, 2.0, 0.0, *_yaw_quat(math.pi / 2)])
    src_eef = np.array([[1.0, 0.0, 0.1, *_yaw_quat(0.0)], [1.2, 0.0, 0.1, *_yaw_quat(0.0)]])
    out = transform_segment(src_eef, src_obj, cur_obj)
    # the first pose sits above the current object; the second is 0.2 m along the object's x (= world +y)
    np.testing.assert_allclose(out[0, :3], [0.0, 2.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(out[1, :3], [0.0, 2.2, 0.1], atol=1e-12)
    np.testing.assert_allclose(np.abs(out[:, 3:]), np.abs([_yaw_quat(math.pi / 2)] * 2), atol=1e-12)


def test_interpolation_and_symmetry():
    a = np.array([0.0, 0.0, 0.0, *_yaw_quat(0.0)])
    b = np.array([1.0, 0.0, 0.0, *_yaw_quat(1.0)])
    path = interpolate_poses(a, b, 4)
    np.testing.assert_allclose(path[:, 0], [0.25, 0.5, 0.75, 1.0])
    np.testing.assert_allclose(path[1, 3:], _yaw_quat(0.5), atol=1e-12)
    # a cube yawed 80 deg is the same cube yawed -10 deg: the frame closest to a yaw-0 source is -10 deg
    cube = np.array([0.0, 0.0, 0.0, *_yaw_quat(math.radians(80))])
    turned = closest_symmetric_pose(cube, a, math.pi / 2)
    np.testing.assert_allclose(np.abs(turned[3:]), np.abs(_yaw_quat(math.radians(-10))), atol=1e-9)


def test_mimic_variants_and_errors(tmp_path):
    assert mimic_variant_of("GalbotG1-PickCube-v0").id == "GalbotG1-PickCube-Mimic-v0"
    assert mimic_variant_of("GalbotG1-StackCube-v0").id == "GalbotG1-StackCube-Mimic-v0"
    with pytest.raises(ValueError) as e:
        mimic_variant_of("GalbotG1-Reach-v0")
    assert "GalbotG1-PickCube-v0" in str(e.value)
    with pytest.raises(FileNotFoundError):
        mimic(tmp_path / "missing.hdf5", episodes=1)


def test_mimic_without_signals_says_what_is_needed(tmp_path):
    from newton_lab.datasets import open_writer

    path = tmp_path / "old.hdf5"
    with open_writer(
        path,
        task_id="GalbotG1-PickCube-v0",
        env_args={
            "newton_lab": {"action_joint_names": [f"left_arm_joint{i}" for i in range(1, 8)] + ["left_gripper_joint"]}
        },
    ) as w:
        w.append_episode({"actions": np.zeros((5, 8), np.float32)}, success=True)
    with pytest.raises(ValueError) as e:
        mimic(path, episodes=1, num_envs=1, device="cpu", progress=False)
    assert "subtask signals" in str(e.value) and "re-collect" in str(e.value)


@pytest.mark.slow
def test_mimic_from_two_sources_generates_successes(pick_env, tmp_path):
    from newton_lab.agents import PlannerAgent

    src = pick_env.collect(
        agent=PlannerAgent.from_task(pick_env.task_id),
        episodes=2,
        path=tmp_path / "src.hdf5",
        max_steps=400,
        progress=False,
    )
    ref = mimic(
        src, episodes=3, num_envs=2, output_path=tmp_path / "gen.hdf5", device="cpu", progress=False, max_attempts=8
    )
    m = ref.metadata
    assert m["successes"] == 3 and m["attempts"] >= 3 and 0 < m["generation_success_rate"] <= 1
    info = read_dataset_info(ref.path)
    assert info["task_id"] == "GalbotG1-PickCube-v0" and info["num_demos"] == 3
    for demo in info["demo_ids"]:
        ep = read_episode(ref.path, demo)
        assert ep["attrs"]["success"] and ep["actions"].shape[1] == 8
        assert ep["datagen"]["subtask_signals"]["grasped_cube"].any()
    ops = [p.operation for p in DatasetRef.open(ref.path).provenance]
    assert ops == ["mimic"]
    assert DatasetRef.open(ref.path).provenance[0].config["source_path"] == str(src.path)


def test_stack_cube_segments_end_clear_of_the_stack(stack_env, tmp_path):
    """Every StackCube segment boundary (over its whole offset range) has the fingertips above the objects
    the next segment's interpolation may cross: a boundary inside the release let the cube_3 segment
    sweep the open fingers through cube_2."""
    from newton_lab.agents import PlannerAgent
    from newton_lab.mimic.source import load_sources
    from newton_lab.robots.g1.kinematics import TcpKinematics
    from newton_lab.task_api.registry import lookup

    stack_env.reseed(stack_env.seed)  # a fresh env's first scene, whatever ran on the shared fixture before
    src = stack_env.collect(
        agent=PlannerAgent.from_task(stack_env.task_id),
        episodes=1,
        path=tmp_path / "s.hdf5",
        max_steps=900,
        progress=False,
    )
    assert src["successes"] == 1
    cfg = lookup("GalbotG1-StackCube-Mimic-v0").mimic
    (demo,) = load_sources(
        src.path, cfg, TcpKinematics(64, device="cpu"), task_id=stack_env.task_id, robot=stack_env.robot
    )
    fingers = 0.05  # fingertips reach this far below the TCP [m]
    for sub in cfg.subtasks[:-1]:
        lo, hi = sub.term_offset_range
        edge = demo.signal_edges[sub.term_signal]
        for end in range(edge + lo, edge + hi + 1):
            tips = demo.target_tcp[end, 2] - fingers
            tops = max(
                demo.objects[name][end, 2] + 0.025
                for name in ("cube_1", "cube_2", "cube_3")
                if name != sub.object_ref or sub.term_signal == "cube_2_on_cube_1"
            )
            held = demo.gripper[end] > 0.1  # a carried cube hangs below the fingertips
            clearance = tips - tops - (0.05 if held else 0.0)
            assert clearance > 0.0, (sub.term_signal, end - edge, round(clearance, 3))
