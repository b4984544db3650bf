"""The G1 binding: the robot the env reads through ``env.robot`` (registry, facts), robot half of the task context,
the action map and its kinds, the model's limits (the gripper's velocity limit measured on real physics), and the
one mecanum formula."""

from __future__ import annotations

import dataclasses

import newton
import numpy as np
import pytest
import torch
import warp as wp
from newton_lab.kernels.actions import KIND_CODE
from torch.testing import assert_close

from newton_lab.envs import NewtonEnv, make_env
from newton_lab.envs.scene import build_scene
from newton_lab.robots.binding import RobotBinding
from newton_lab.robots.bound import ACTION_KINDS, BoundRobot
from newton_lab.robots.g1 import spec
from newton_lab.robots.g1.mecanum import wheel_gains
from newton_lab.robots.mecanum import twist_to_wheels_torch, wheels_to_twist_torch
from newton_lab.robots.registry import register_robot, robot_binding, robot_names
from newton_lab.task_api.cfg import ActionTermCfg
from newton_lab.task_api.registry import lookup

PICK = "GalbotG1-PickCube-v0"


@pytest.fixture(scope="module")
def pick_cfg():
    return lookup(PICK).make_cfg(None)


@pytest.fixture(scope="module")
def layout(pick_cfg):
    with wp.ScopedDevice("cpu"):
        return build_scene(pick_cfg, 1, "cpu")


def _bind(layout, *terms: ActionTermCfg, arm: str = "left") -> BoundRobot:
    return BoundRobot.from_layout(robot_binding("g1"), layout, actions=list(terms), arm=arm)


# ---------------------------------------------------------------- the robot behind one binding
def test_the_env_reads_the_robot_its_task_names(pick_env, pick_cfg):
    g1 = robot_binding("g1")
    assert pick_cfg.robot == "g1" and pick_env.robot is g1 and pick_env.joints.binding.robot is g1
    assert "g1" in robot_names()
    assert g1.arm("left").joints == spec.LEFT_ARM_JOINTS and g1.arm("right").gripper == spec.RIGHT_GRIPPER_JOINT
    assert g1.wheel_gains == pytest.approx(wheel_gains())
    assert (g1.gripper_open, g1.gripper_closed) == (spec.GRIPPER_OPEN, spec.GRIPPER_CLOSED)
    base = pick_env.joints.binding.context.base_coord
    assert pick_env.joints.coords(g1.base_planar_joints) == [base + i for i in range(3)]
    with pytest.raises(ValueError, match="unknown robot 'h1'; registered robots: .*g1"):
        robot_binding("h1")
    with pytest.raises(ValueError, match="unknown arm 'middle'"):
        g1.arm("middle")


def test_a_second_robot_is_one_registration(layout):
    """The seam a second robot would use: its own binding, registered by name, bound by the same generic code
    (here the G1's facts under another name, with a wider gripper)."""
    other = dataclasses.replace(robot_binding("g1"), name="g1_wide_gripper", gripper_closed=1.5)
    assert register_robot(other) is robot_binding("g1_wide_gripper")
    with pytest.raises(ValueError, match="already registered"):
        register_robot(dataclasses.replace(other))
    bound = BoundRobot.from_layout(
        other, layout, actions=[ActionTermCfg(name="gripper", group="left_gripper", type="binary")]
    )
    assert isinstance(other, RobotBinding) and bound.robot is other
    assert (bound.actions.low[0], bound.actions.high[0]) == (0.0, 1.5)  # the binary column clips to its range
    assert bound.context.gripper_closed == 1.5


def test_the_task_context_follows_the_binding_without_g1_counts(layout):
    """The robot half of the task context is what the binding describes: a robot without lift joints gets none,
    a shorter arm its own joints, another gripper range its own (the kernels loop over these, not over the G1's)."""
    g1 = robot_binding("g1")
    arm = dataclasses.replace(g1.arms["left"], joints=g1.arms["left"].joints[:6])
    other = dataclasses.replace(
        g1, name="g1_no_lift", leg_joints=(), arms={**g1.arms, "left": arm}, gripper_open=0.1, gripper_closed=0.9
    )
    ctx = BoundRobot.from_layout(other, layout, actions=[], arm="left").context
    coord = layout.joints.coord
    assert ctx.lift_coords == () and ctx.arm_coords == tuple(coord[j] for j in spec.LEFT_ARM_JOINTS[:6])
    assert (ctx.gripper_open, ctx.gripper_closed) == (0.1, 0.9)
    from newton_lab.kernels.context import TaskContext

    with wp.ScopedDevice("cpu"):
        task_ctx = TaskContext()
        ctx.fill(task_ctx)
    assert task_ctx.lift_coords.shape == (0,) and task_ctx.arm_coords.shape == (6,)


def test_nothing_falls_back_to_the_g1_when_no_robot_is_given(tmp_path):
    """Where a robot is needed and none is given, one line says so (no default robot is taken instead)."""
    from newton_lab.agents.teleop.contracts import FrameMapper, leg_targets
    from newton_lab.envs.cameras import Cameras
    from newton_lab.mimic.source import load_sources

    calls = {
        "leg_targets": lambda: leg_targets(0.1, None),
        "FrameMapper": lambda: FrameMapper("mobile_full_body", [], robot=None),
        "Cameras": lambda: Cameras(
            {}, model=None, state=None, num_envs=1, bodies_per_world=1, entity_names=[], robot=None
        ),
        "load_sources": lambda: load_sources(tmp_path / "none.hdf5", None, None, task_id="x", robot=None),
    }
    for user, call in calls.items():
        with pytest.raises(ValueError, match=rf"^{user} needs the robot it works for \(robot=env.robot") as err:
            call()
        assert "\n" not in str(err.value)


# ---------------------------------------------------------------- robot half of the context
def test_robot_context_from_joint_index(layout, pick_cfg):
    ctx = _bind(layout).context
    coord = layout.joints.coord
    assert ctx.robot_coords == layout.robot_coords == 34
    assert ctx.base_coord == coord["base_x"] and ctx.lift_coords == tuple(coord[j] for j in spec.LEG_JOINTS)
    assert (ctx.gripper_open, ctx.gripper_closed) == (spec.GRIPPER_OPEN, spec.GRIPPER_CLOSED)
    assert ctx.gripper_coord == coord["left_gripper_joint"]
    assert ctx.arm_coords == tuple(coord[j] for j in spec.LEFT_ARM_JOINTS)
    assert ctx.tcp_body == layout.joints.body["left_arm_link7"]
    assert ctx.tcp_offset_pos == spec.TCP_OFFSET_POS and ctx.tcp_offset_quat == spec.TCP_OFFSET_QUAT
    right = _bind(layout, arm="right").context
    assert right.arm_coords == tuple(coord[j] for j in spec.RIGHT_ARM_JOINTS)
    with pytest.raises(ValueError, match="unknown arm 'middle'"):
        _bind(layout, arm="middle")


def test_env_context_is_the_binding(pick_env):
    ctx, bound = pick_env.task.context, pick_env.joints.binding.context
    assert ctx.robot_coords == bound.robot_coords == 34
    assert (ctx.base_coord, ctx.gripper_coord, ctx.tcp_body, ctx.gripper_open, ctx.gripper_closed) == (
        bound.base_coord,
        bound.gripper_coord,
        bound.tcp_body,
        bound.gripper_open,
        bound.gripper_closed,
    )
    assert tuple(ctx.arm_coords.numpy()) == bound.arm_coords and tuple(ctx.lift_coords.numpy()) == bound.lift_coords


# ---------------------------------------------------------------- the action map
def test_action_map_columns_and_kinds(layout):
    m = _bind(
        layout,
        ActionTermCfg(name="base_action", group="base", type="velocity", clip=(-4.5, 4.5)),
        ActionTermCfg(name="arm_action", group="left_arm", type="relative"),
        ActionTermCfg(name="gripper_action", group="left_gripper", type="binary"),
    ).actions
    joints = layout.joints
    assert m.joint_names == spec.BASE_WHEEL_JOINTS + spec.LEFT_ARM_JOINTS + (spec.LEFT_GRIPPER_JOINT,)
    assert m.kinds == ("velocity",) * 4 + ("relative",) * 7 + ("binary",)
    assert m.terms == {"base_action": slice(0, 4), "arm_action": slice(4, 11), "gripper_action": slice(11, 12)}
    assert m.wheel_col == 0 and m.dim == 12
    assert m.index[:4].tolist() == [joints.dof[j] for j in spec.BASE_WHEEL_JOINTS]
    assert m.index[4:].tolist() == [joints.coord[j] for j in spec.LEFT_ARM_JOINTS + (spec.LEFT_GRIPPER_JOINT,)]
    assert m.low[:4].tolist() == [-4.5] * 4 and m.high[:4].tolist() == [4.5] * 4
    assert (m.low[11], m.high[11]) == (spec.GRIPPER_OPEN, np.float32(spec.GRIPPER_CLOSED))
    assert np.isinf(m.low[4:11]).all() and m.scale.tolist() == [1.0] * 12
    assert (m.target_low[4], m.target_high[4]) == (np.float32(-3.05), np.float32(3.05))  # left_arm_joint1 range
    assert set(KIND_CODE) == set(ACTION_KINDS)


@pytest.mark.parametrize(
    "term, match",
    [
        (
            ActionTermCfg(name="arm_action", group="left_arm", type="absolut"),
            r"action term 'arm_action': unknown type 'absolut'; valid kinds: absolute, relative, velocity, binary",
        ),
        (ActionTermCfg(name="tail", group="tail", type="absolute"), r"unknown group 'tail'; valid groups: base, "),
        (
            ActionTermCfg(name="arm_action", group="left_arm", type="velocity"),
            r"type 'velocity' does not drive group 'left_arm'; use absolute\|relative",
        ),
        (
            ActionTermCfg(name="base_action", group="base", type="absolute"),
            r"does not drive group 'base'; use velocity",
        ),
        (ActionTermCfg(name="leg_action", group="legs", type="binary"), r"does not drive group 'legs'"),
    ],
)
def test_action_map_refuses_unknown_kinds(layout, term, match):
    with pytest.raises(ValueError, match=match) as info:
        _bind(layout, term)
    assert "\n" not in str(info.value)


def test_action_map_refuses_a_joint_twice(layout):
    term = ActionTermCfg(name="arm_action", group="left_arm")
    with pytest.raises(ValueError, match="'left_arm_joint1' is in action terms 'arm_action' and 'arm_again'"):
        _bind(layout, term, dataclasses.replace(term, name="arm_again"))


def test_relative_action_adds_to_the_current_target(pick_cfg):
    cfg = dataclasses.replace(
        pick_cfg,
        actions=[
            ActionTermCfg(name="arm_action", group="left_arm", type="relative"),
            ActionTermCfg(name="gripper_action", group="left_gripper", type="binary"),
        ],
    )
    env = NewtonEnv(cfg, num_envs=2, device="cpu", capture=False)
    coords = [env.sim.layout.joints.coord[j] for j in spec.LEFT_ARM_JOINTS]
    targets = lambda: wp.to_torch(env.control.joint_target_q).view(2, -1)[:, coords].clone()  # noqa: E731
    start = targets()
    hold = env.current_action()
    assert_close(hold[:, :7], torch.zeros(2, 7))  # relative columns hold with 0
    assert_close(hold[:, 7], torch.zeros(2))  # the binary gripper column holds its (open) target
    a = hold.clone()
    a[0, 0] = 0.02
    for _ in range(3):
        env.step(a)
    expected = start.clone()
    expected[0, 0] += 0.06
    assert_close(targets(), expected, atol=1e-6, rtol=0)
    a[0, 0] = 100.0  # the accumulated target stays within the joint's range
    env.step(a)
    assert float(targets()[0, 0]) == pytest.approx(3.05)


# ---------------------------------------------------------------- limits in the model
def test_spec_limits_are_in_the_model(layout):
    model, joints = layout.model, layout.joints
    vel, effort = model.joint_velocity_limit.numpy(), model.joint_effort_limit.numpy()
    mode = model.joint_target_mode.numpy()
    lower, upper = model.joint_limit_lower.numpy(), model.joint_limit_upper.numpy()
    for name, limit in spec.JOINT_VELOCITY_LIMITS.items():
        d = joints.dof[name]
        assert vel[d] == pytest.approx(limit)
        assert mode[d] == int(newton.JointTargetMode.POSITION_VELOCITY)
    for name, limit in spec.JOINT_EFFORT_LIMITS.items():
        assert effort[joints.dof[name]] == pytest.approx(limit)
    for name in (spec.LEFT_GRIPPER_JOINT, spec.RIGHT_GRIPPER_JOINT):  # open .. closed is the joint's range
        d = joints.dof[name]
        assert (lower[d], upper[d]) == pytest.approx((spec.GRIPPER_OPEN, spec.GRIPPER_CLOSED))
    limits = _bind(layout).limits
    assert limits.max_rate[joints.coord[spec.LEFT_GRIPPER_JOINT]] == pytest.approx(spec.GRIPPER_VELOCITY_LIMIT)
    assert int(np.count_nonzero(limits.max_rate)) == len(spec.JOINT_VELOCITY_LIMITS)


def _close_gripper(env, steps: int) -> tuple[list[float], float]:
    """Command the gripper closed from open; per-step positions and the peak speed over every substep."""
    env.reset()
    c, d = (getattr(env.sim.layout.joints, k)[spec.LEFT_GRIPPER_JOINT] for k in ("coord", "dof"))
    q, qd = wp.to_torch(env.state.joint_q), wp.to_torch(env.state.joint_qd)
    env.buffers.actions.copy_(env.current_action())
    env.buffers.actions[:, env.action_joint_names.index(spec.LEFT_GRIPPER_JOINT)] = spec.GRIPPER_CLOSED
    positions, peak = [], 0.0
    with wp.ScopedDevice(env.device):
        for _ in range(steps):
            env.sim.apply_actions()
            for _ in range(env.cfg.decimation):
                env.sim.substep()
                peak = max(peak, abs(float(qd[d])))
            positions.append(float(q[c]))
    return positions, peak


def test_gripper_velocity_limit_on_real_physics():
    env = make_env(PICK, num_envs=1, device="cpu", capture=False)
    limited, peak = _close_gripper(env, 16)
    # the same env with its setpoint limit switched off: the drive as it was before the limit
    env.joints.actuation.max_step.zero_()
    env.joints.actuation.dof_limited.zero_()
    free, free_peak = _close_gripper(env, 16)
    print(
        f"gripper closing: before peak {free_peak:.2f} rad/s (first step {free[0] / 0.05:.2f} rad/s), "
        f"after peak {peak:.2f} rad/s (first step {limited[0] / 0.05:.2f} rad/s)"
    )
    assert free_peak > 5.0 and free[0] / env.cfg.control_dt > 5.0  # ~6.9 rad/s over the first step
    assert peak <= 1.1 * spec.GRIPPER_VELOCITY_LIMIT
    rates = np.diff([0.0] + limited) / env.cfg.control_dt
    assert rates.max() <= 1.1 * spec.GRIPPER_VELOCITY_LIMIT
    assert limited[0] > 0.05, "the gripper still leaves 'open' within one control step"
    assert limited[-1] == pytest.approx(spec.GRIPPER_CLOSED, abs=0.01)  # closed after 0.8 s
    # the command (the target agents hold) is the closed value at once; the drive's setpoint follows it
    c = env.sim.layout.joints.coord[spec.LEFT_GRIPPER_JOINT]
    assert float(wp.to_torch(env.control.joint_target_q)[c]) == pytest.approx(spec.GRIPPER_CLOSED)


def test_reset_rows_restart_their_setpoints():
    env = make_env(PICK, num_envs=1, device="cpu", capture=False)
    a = env.current_action()
    a[:, env.action_joint_names.index(spec.LEFT_GRIPPER_JOINT)] = spec.GRIPPER_CLOSED
    env.step(a)
    c = env.sim.layout.joints.coord[spec.LEFT_GRIPPER_JOINT]
    assert 0.0 < float(wp.to_torch(env.sim.drive.joint_target_q)[c]) < spec.GRIPPER_CLOSED
    env.reset()
    assert float(wp.to_torch(env.sim.drive.joint_target_q)[c]) == float(wp.to_torch(env.control.joint_target_q)[c])


def test_a_gripper_placed_by_hand_stays_where_it_was_placed():
    """``set_joint_positions`` moves position, target and drive setpoint together: a gripper placed closed stays
    closed under a holding action. Written into ``state`` and ``control`` alone, the rate-limited setpoint stays
    open and the drive pulls the gripper open again, until ``sync_drive``."""
    env = make_env(PICK, num_envs=2, device="cpu", capture=False)
    env.reset()
    c = env.sim.layout.joints.coord[spec.LEFT_GRIPPER_JOINT]
    column = lambda a: wp.to_torch(a).view(2, -1)[:, c].tolist()  # noqa: E731
    env.joints.set_positions([spec.LEFT_GRIPPER_JOINT], [spec.GRIPPER_CLOSED], env_ids=[1])
    for array in (env.state.joint_q, env.control.joint_target_q, env.sim.drive.joint_target_q):
        assert column(array) == pytest.approx([spec.GRIPPER_OPEN, spec.GRIPPER_CLOSED])
    assert env.joints.positions([spec.LEFT_GRIPPER_JOINT])[:, 0].tolist() == pytest.approx([0.0, spec.GRIPPER_CLOSED])
    for _ in range(3):
        env.step(env.current_action())  # hold every target
    assert column(env.state.joint_q)[1] == pytest.approx(spec.GRIPPER_CLOSED, abs=0.05)

    # by hand: position and target written, the setpoint left open
    env.reset()
    for array in (env.state.joint_q, env.control.joint_target_q):
        wp.to_torch(array).view(2, -1)[1, c] = spec.GRIPPER_CLOSED
    assert column(env.sim.drive.joint_target_q)[1] == spec.GRIPPER_OPEN  # stale
    env.step(env.current_action())
    assert column(env.state.joint_q)[1] < spec.GRIPPER_CLOSED - 0.2  # pulled open by the stale setpoint
    env.joints.sync_drive([1])
    assert column(env.sim.drive.joint_target_q) == pytest.approx([spec.GRIPPER_OPEN, spec.GRIPPER_CLOSED])
    with pytest.raises(ValueError, match=r"values has shape \(2,\); pass \(1,\) or \(1, 1\)"):
        env.joints.set_positions([spec.LEFT_GRIPPER_JOINT], [0.0, 1.0], env_ids=[0])


# ---------------------------------------------------------------- the one wheel formula
def test_mecanum_formula_reference_vectors_and_inverse():
    lin, yaw = wheel_gains()
    assert (lin, yaw) == pytest.approx((7.0711, 10.0161), abs=1e-4)
    twist = torch.tensor([[0.2, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 1.0], [0.1, -0.3, 0.7]])
    wheels = twist_to_wheels_torch(twist, (lin, yaw))
    assert_close(
        wheels[:3],
        torch.tensor([[-1.4142, -1.4142, 1.4142, 1.4142], [1.4142, -1.4142, -1.4142, 1.4142], [10.0161] * 4]),
        atol=1e-4,
        rtol=0,
    )
    assert_close(wheels_to_twist_torch(wheels, (lin, yaw)), twist, atol=1e-6, rtol=0)
