"""G1 action packers: wheel kinematics, named-joint packing, grippers, dispatcher, validation (no physics)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch.testing import assert_close

from newton_lab.robots.g1 import spec
from newton_lab.robots.g1.packers import (
    base_twist_to_wheel_velocities,
    g1_action,
    gripper_binary,
    pack_joint_positions,
    pack_relative_joint_positions,
    wheel_gains,
    wheel_velocities_to_base_twist,
)
from newton_lab.tasks.common.config.g1 import postures

ACT = spec.G1_ACTION_JOINT_NAMES
A = len(ACT)
TOL = {"atol": 1e-4, "rtol": 0.0}


def _t(*v: float) -> torch.Tensor:
    return torch.tensor([v], dtype=torch.float32)


def _col(name: str) -> int:
    return ACT.index(name)


# ---------------------------------------------------------------- wheels
def test_wheel_gains_reference_values():
    lin, yaw = wheel_gains()
    assert lin == pytest.approx(7.0711, abs=1e-4)
    assert yaw == pytest.approx(10.0161, abs=1e-4)


@pytest.mark.parametrize(
    ("twist", "expected"),
    [
        ((0.2, 0.0, 0.0), (-1.4142, -1.4142, 1.4142, 1.4142)),
        ((0.0, 0.2, 0.0), (1.4142, -1.4142, -1.4142, 1.4142)),
        ((0.0, 0.0, 1.0), (10.0161, 10.0161, 10.0161, 10.0161)),
    ],
)
def test_wheel_reference_vectors(twist, expected):
    out = base_twist_to_wheel_velocities(*twist)
    assert out.shape == (1, 4) and out.dtype == torch.float32
    assert_close(out, _t(*expected), **TOL)


def test_wheel_scales_and_broadcast_num_envs():
    out = base_twist_to_wheel_velocities(0.2, 0.0, 1.0, num_envs=3, lin_scale=0.5, ang_scale=2.0)
    row = _t(-0.7071 + 20.0322, -0.7071 + 20.0322, 0.7071 + 20.0322, 0.7071 + 20.0322)
    assert_close(out, row.expand(3, 4), **TOL)


def test_wheel_per_row_tensors_infer_num_envs():
    out = base_twist_to_wheel_velocities(torch.tensor([0.2, 0.0]), torch.tensor([0.0, 0.2]), 0.0)
    expected = torch.tensor([[-1.4142, -1.4142, 1.4142, 1.4142], [1.4142, -1.4142, -1.4142, 1.4142]])
    assert_close(out, expected, **TOL)


def test_wheel_env_indices_zero_elsewhere():
    out = base_twist_to_wheel_velocities(0.2, 0.0, 0.0, num_envs=4, env_indices=[2, 0])
    assert_close(out[[0, 2]], _t(-1.4142, -1.4142, 1.4142, 1.4142).expand(2, 4), **TOL)
    assert torch.count_nonzero(out[[1, 3]]) == 0


def test_wheel_env_indices_per_row_values():
    out = base_twist_to_wheel_velocities(np.array([0.0, 0.2]), 0.0, 0.0, num_envs=3, env_indices=[1, 2])
    assert torch.count_nonzero(out[:2]) == 0
    assert_close(out[2:], _t(-1.4142, -1.4142, 1.4142, 1.4142), **TOL)


def test_wheel_round_trip():
    gen = torch.Generator().manual_seed(0)
    vx, vy, wz = (torch.rand(16, generator=gen) * 2 - 1 for _ in range(3))
    for kw in ({}, {"lin_scale": 0.7, "ang_scale": 1.3}):
        wheels = base_twist_to_wheel_velocities(vx, vy, wz, **kw)
        rvx, rvy, rwz = wheel_velocities_to_base_twist(wheels, **kw)
        assert_close(rvx, vx, **TOL)
        assert_close(rvy, vy, **TOL)
        assert_close(rwz, wz, **TOL)


def test_wheel_inverse_single_vector():
    vx, vy, wz = wheel_velocities_to_base_twist([-1.4142, -1.4142, 1.4142, 1.4142])
    assert_close(torch.stack((vx, vy, wz)), torch.tensor([0.2, 0.0, 0.0]), **TOL)


# ---------------------------------------------------------------- absolute packing
def test_pack_absolute_broadcast_zero_default():
    out = pack_joint_positions(["leg_joint2", "left_arm_joint4"], [0.6, -1.5], action_joint_names=ACT, num_envs=3)
    assert out.shape == (3, A) and out.dtype == torch.float32
    expected = torch.zeros(3, A)
    expected[:, _col("leg_joint2")] = 0.6
    expected[:, _col("left_arm_joint4")] = -1.5
    assert_close(out, expected)


def test_pack_absolute_per_row_values_and_baseline_vector():
    baseline = torch.arange(A, dtype=torch.float32)
    out = pack_joint_positions(
        ("right_arm_joint1",),
        [[1.0], [2.0]],
        action_joint_names=ACT,
        num_envs=2,
        baseline=baseline,
    )
    expected = baseline.repeat(2, 1)
    expected[:, _col("right_arm_joint1")] = torch.tensor([1.0, 2.0])
    assert_close(out, expected)
    assert_close(baseline, torch.arange(A, dtype=torch.float32))  # input not mutated


def test_pack_absolute_env_indices_keep_current():
    current = torch.full((4, A), 0.5)
    out = pack_joint_positions(
        ["leg_joint1"], [[0.1], [0.3]], action_joint_names=ACT, num_envs=4, current=current, env_indices=[3, 1]
    )
    expected = current.clone()
    expected[3, _col("leg_joint1")] = 0.1
    expected[1, _col("leg_joint1")] = 0.3
    assert_close(out, expected)
    assert_close(current, torch.full((4, A), 0.5))


def test_pack_absolute_baseline_beats_current():
    out = pack_joint_positions(
        [], [], action_joint_names=ACT, num_envs=2, baseline=torch.ones(2, A), current=torch.full((2, A), 9.0)
    )
    assert_close(out, torch.ones(2, A))


def test_pack_absolute_numpy_values_custom_order():
    order = ("left_arm_joint2", "leg_joint1")
    out = pack_joint_positions(["leg_joint1"], np.array([0.25]), action_joint_names=order, num_envs=1)
    assert_close(out, torch.tensor([[0.0, 0.25]]))


# ---------------------------------------------------------------- relative packing
def test_pack_relative_scale_and_zeros():
    out = pack_relative_joint_positions(
        ["left_arm_joint1", "left_arm_joint7"], [1.0, -2.0], action_joint_names=ACT, num_envs=3, env_indices=[1]
    )
    expected = torch.zeros(3, A)
    expected[1, _col("left_arm_joint1")] = 0.05
    expected[1, _col("left_arm_joint7")] = -0.1
    assert_close(out, expected)


def test_pack_relative_custom_scale():
    out = pack_relative_joint_positions(["leg_joint3"], [2.0], action_joint_names=ACT, num_envs=1, scale=0.5)
    assert out[0, _col("leg_joint3")].item() == pytest.approx(1.0)
    assert torch.count_nonzero(out) == 1


# ---------------------------------------------------------------- grippers
def test_gripper_binary_inputs():
    assert_close(gripper_binary(True), torch.tensor([[spec.GRIPPER_OPEN]]))
    assert_close(gripper_binary(False), torch.tensor([[spec.GRIPPER_CLOSED]]))
    assert_close(gripper_binary([True, False]), torch.tensor([[0.0], [1.2]]))
    assert_close(gripper_binary(np.array([[True, False]])), torch.tensor([[0.0, 1.2]]))
    out = gripper_binary(torch.tensor([[False, True], [True, True]]))
    assert out.dtype == torch.float32
    assert_close(out, torch.tensor([[1.2, 0.0], [0.0, 0.0]]))
    assert_close(gripper_binary([1, 0]), torch.tensor([[0.0], [1.2]]))


def test_gripper_binary_rows_keep_the_baseline():
    """Like the joint packers: flags for some rows, every other row keeps its baseline targets."""
    current = torch.tensor([[1.2], [0.0], [0.7]])  # closed, open, half-way
    out = gripper_binary(True, env_indices=[0], baseline=current)  # open row 0 only; N from the baseline
    assert_close(out, torch.tensor([[0.0], [0.0], [0.7]]))
    assert_close(current, torch.tensor([[1.2], [0.0], [0.7]]))  # the baseline is not written
    out = gripper_binary([False, True], env_indices=[2, 1], baseline=current)  # per selected row, in its order
    assert_close(out, torch.tensor([[1.2], [0.0], [1.2]]))
    two = gripper_binary([[False, True]], num_envs=3, env_indices=torch.tensor([1]), baseline=[0.3, 0.4])
    assert_close(two, torch.tensor([[0.3, 0.4], [1.2, 0.0], [0.3, 0.4]]))  # (G,) baseline, one row of flags
    assert_close(gripper_binary(False, num_envs=2), torch.tensor([[1.2], [1.2]]))  # every row
    assert_close(g1_action("right_gripper", "binary", open_flags=True, env_indices=[1], baseline=current),
                 torch.tensor([[1.2], [0.0], [0.7]]))


# ---------------------------------------------------------------- dispatcher
def test_g1_action_dispatch():
    assert_close(g1_action("base", "velocity", vx=0.2), _t(-1.4142, -1.4142, 1.4142, 1.4142), **TOL)
    legs = g1_action("legs", values=spec.leg_lift(0.2), num_envs=2)
    assert_close(legs, torch.tensor([spec.leg_lift(0.2)] * 2, dtype=torch.float32))
    arm = g1_action("right_arm", "relative", joint_names=["right_arm_joint2"], deltas=[1.0], num_envs=1)
    assert arm.shape == (1, 7)
    assert_close(arm, torch.tensor([[0.0, 0.05, 0, 0, 0, 0, 0]]))
    left = g1_action("left_arm", "absolute", values=postures.CARRY_LEFT_ARM, num_envs=1)
    assert_close(left, torch.tensor([postures.CARRY_LEFT_ARM], dtype=torch.float32))
    assert_close(g1_action("left_gripper", "binary", open_flags=[False]), torch.tensor([[1.2]]))


# ---------------------------------------------------------------- validation
def _one_line_error(match: str, fn, *args, **kw) -> None:
    with pytest.raises(ValueError, match=match) as info:
        fn(*args, **kw)
    assert "\n" not in str(info.value)


def test_error_unknown_joint_lists_valid():
    with pytest.raises(ValueError, match="unknown joint") as info:
        pack_joint_positions(["nope"], [0.0], action_joint_names=ACT, num_envs=1)
    assert "leg_joint1" in str(info.value) and "wheel4_joint" in str(info.value)
    assert "\n" not in str(info.value)


def test_error_duplicate_joint_names():
    _one_line_error(
        "duplicate joint names", pack_joint_positions, ["leg_joint1"] * 2, [0, 0], action_joint_names=ACT, num_envs=1
    )


def test_error_duplicate_action_joint_names():
    _one_line_error(
        "duplicate joint names", pack_relative_joint_positions, ["a"], [0], action_joint_names=["a", "a"], num_envs=1
    )


def test_error_values_length_mismatch():
    _one_line_error(
        "shape", pack_joint_positions, ["leg_joint1", "leg_joint2"], [0.0], action_joint_names=ACT, num_envs=1
    )


def test_error_values_rows_mismatch():
    _one_line_error(
        "shape", pack_relative_joint_positions, ["leg_joint1"], [[0.0]] * 3, action_joint_names=ACT, num_envs=2
    )


def test_error_empty_env_indices():
    _one_line_error(
        "empty", pack_joint_positions, ["leg_joint1"], [0.0], action_joint_names=ACT, num_envs=2, env_indices=[]
    )


def test_error_duplicate_env_indices():
    _one_line_error(
        "duplicate env_indices", pack_joint_positions, ["leg_joint1"], [0.0], action_joint_names=ACT, num_envs=3,
        env_indices=[1, 1],
    )


@pytest.mark.parametrize("bad", [[2], [-1]])
def test_error_env_index_out_of_range(bad):
    _one_line_error(
        r"out of range \[0, 2\)", pack_relative_joint_positions, ["leg_joint1"], [0.0], action_joint_names=ACT,
        num_envs=2, env_indices=bad,
    )
    _one_line_error(r"out of range", base_twist_to_wheel_velocities, 0.1, num_envs=2, env_indices=bad)


def test_error_baseline_wrong_shape():
    _one_line_error(
        "baseline has shape", pack_joint_positions, ["leg_joint1"], [0.0], action_joint_names=ACT, num_envs=2,
        baseline=torch.zeros(A - 1),
    )


def test_error_current_wrong_shape():
    _one_line_error(
        "current has shape", pack_joint_positions, ["leg_joint1"], [0.0], action_joint_names=ACT, num_envs=2,
        current=torch.zeros(A),
    )


def test_error_wheel_inputs():
    _one_line_error("lengths differ", base_twist_to_wheel_velocities, torch.zeros(2), torch.zeros(3))
    _one_line_error("needs num_envs", base_twist_to_wheel_velocities, 0.1, env_indices=[0])
    _one_line_error("wheels has shape", wheel_velocities_to_base_twist, torch.zeros(2, 3))


def test_error_gripper_non_boolean():
    _one_line_error("must be booleans", gripper_binary, [0.5])


def test_error_gripper_rows():
    base = torch.zeros(3, 1)
    _one_line_error("env_indices needs baseline", gripper_binary, True, num_envs=3, env_indices=[0])
    _one_line_error(r"open_flags has shape \(2, 1\) for 1 row\(s\) of 1 gripper", gripper_binary, [True, False],
                    env_indices=[0], baseline=base)
    _one_line_error("out of range", gripper_binary, True, env_indices=[3], baseline=base)
    _one_line_error("baseline has shape", gripper_binary, True, env_indices=[0], baseline=torch.zeros(3, 1, 1))
    _one_line_error(r"baseline has shape \(2, 1\)", gripper_binary, True, num_envs=3, env_indices=[0],
                    baseline=torch.zeros(2, 1))


def test_error_g1_action_unknown_group_and_type():
    with pytest.raises(ValueError, match="unknown group") as info:
        g1_action("tail", "absolute")
    assert "left_arm" in str(info.value) and "velocity" in str(info.value)
    _one_line_error("not valid for group 'base'; use velocity", g1_action, "base", "absolute")
    _one_line_error("use binary", g1_action, "left_gripper", "relative")
