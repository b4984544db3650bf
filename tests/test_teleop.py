"""Teleoperation: GP001 mapping from synthetic frames, the frame -> action mapper per contract, the keyboard
device on a pipe, the review prompt, the replay device re-driving an expert demo on real physics, and the
keep / drop / exit loop writing (and dropping) demos."""

from __future__ import annotations

import io
import os

import numpy as np
import pytest
import torch

from newton_lab.agents.teleop import FrameMapper, TeleopFrame, review_demo
from newton_lab.agents.teleop.contracts import CONTRACTS, leg_targets
from newton_lab.agents.teleop.devices import KeyboardDevice
from newton_lab.agents.teleop.devices.gp001 import Gp001Device, map_gp001
from newton_lab.robots.g1 import spec
from newton_lab.robots.registry import robot_binding

G1 = robot_binding("g1")
FULL_BODY = [j for g in CONTRACTS["mobile_full_body"] for j in spec.JOINT_GROUPS[g]]


def _raw(axes=(0.0,) * 10, left=None, right=None, buttons=()):
    state = [0] * 18
    for b in buttons:
        state[b - 1] = 1
    joints = {}
    if left is not None:
        joints["left_arm"] = {"position": list(left)}
    if right is not None:
        joints["right_arm"] = {"position": list(right)}
    return {
        "timestamp": 0.0,
        "action_list": {"axes": list(axes), "buttons": []},
        "joint_states": joints,
        "button_state": state,
    }


def _axes(**kv):
    axes = [0.0] * 10
    for k, v in kv.items():
        axes[int(k[1:])] = v
    return axes


def test_gp001_gripper_threshold_is_035():
    frame, _ = map_gp001(_raw(_axes(a3=0.35, a4=0.3499)), height=0.0)
    assert frame.gripper_open == {"left": True, "right": False}
    frame, _ = map_gp001(_raw(_axes(a3=0.0, a4=0.7)), height=0.0)
    assert frame.gripper_open == {"left": False, "right": True}


def test_gp001_twist_scaling_and_hold_buttons():
    frame, h = map_gp001(_raw(_axes(a0=0.4, a1=-0.2, a2=1.0, a5=1.0)), height=0.0, speed=0.5)
    assert frame.base_twist == pytest.approx((0.2, -0.1, 0.5))
    assert h == pytest.approx(0.05)  # axes[5] * 0.05 per frame
    mapper = FrameMapper("mobile_full_body", FULL_BODY, robot=G1)
    out = mapper(TeleopFrame(base_twist=(0.2, 0.0, 0.0)), torch.zeros(1, len(FULL_BODY)))
    wheels = out[0, [FULL_BODY.index(j) for j in spec.BASE_WHEEL_JOINTS]]
    assert wheels.tolist() == pytest.approx([-1.4142, -1.4142, 1.4142, 1.4142], abs=1e-3)  # the reference's mixing
    for button in (17, 18):  # held: no twist, the height stays
        frame, h2 = map_gp001(_raw(_axes(a0=1.0, a5=1.0), buttons=[button]), height=h)
        assert frame.base_twist is None and h2 == h


def test_leg_clamps_and_body_height_mapping():
    assert leg_targets(0.1, G1).tolist() == pytest.approx([0.1, 0.3, 0.2, 0.0, 0.0])
    assert leg_targets(5.0, G1).tolist() == pytest.approx([1.01, 2.65, 2.39, 0.0, 0.0])
    assert leg_targets(-1.0, G1).tolist() == pytest.approx([-0.02, -0.02, -0.02, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"leg_targets needs the robot it works for \(robot=env.robot"):
        leg_targets(0.1, None)  # no default robot to fall back to
    mapper = FrameMapper("mobile_full_body", FULL_BODY, robot=G1)
    out = mapper(TeleopFrame(body_height=0.5), torch.zeros(1, len(FULL_BODY)))
    legs = out[0, [FULL_BODY.index(j) for j in spec.LEG_JOINTS]]
    assert legs.tolist() == pytest.approx([0.5, 1.5, 1.0, 0.0, 0.0])


@pytest.mark.parametrize("policy", ["hold", "zero"])
def test_missing_joints_follow_the_no_frame_policy(policy):
    current = torch.arange(len(FULL_BODY), dtype=torch.float32).reshape(1, -1) + 1.0
    left = np.linspace(0.1, 0.7, 7)
    frame, _ = map_gp001(_raw(_axes(a3=0.7), left=left), height=0.0)  # no right-arm joints in the frame
    out = FrameMapper("mobile_full_body", FULL_BODY, robot=G1, no_frame_policy=policy)(frame, current)
    cols = {g: [FULL_BODY.index(j) for j in spec.JOINT_GROUPS[g]] for g in CONTRACTS["mobile_full_body"]}
    assert out[0, cols["left_arm"]].tolist() == pytest.approx(left.tolist())  # leader arm copied 1:1
    right = out[0, cols["right_arm"]]
    assert right.tolist() == (current[0, cols["right_arm"]].tolist() if policy == "hold" else [0.0] * 7)
    assert out[0, cols["left_gripper"]].item() == spec.GRIPPER_OPEN
    assert out[0, cols["right_gripper"]].item() == pytest.approx(spec.GRIPPER_CLOSED)  # axes[4] = 0 < 0.35
    # no frame at all: grippers open by default, arms held or zeroed
    out = FrameMapper("left_arm_manipulation", FULL_BODY, robot=G1, no_frame_policy=policy)(None, current)
    assert out[0, cols["left_gripper"]].item() == spec.GRIPPER_OPEN


def test_bad_policy_contract_and_device_names_fail_in_one_line():
    with pytest.raises(ValueError, match="no_frame_policy 'keep' is unknown; use one of hold, zero"):
        FrameMapper("left_arm_manipulation", FULL_BODY, robot=G1, no_frame_policy="keep")
    with pytest.raises(ValueError, match="unknown teleop contract 'both_arms'"):
        FrameMapper("both_arms", FULL_BODY, robot=G1)
    from newton_lab.agents.teleop import TeleopAgent

    with pytest.raises(ValueError, match="unknown teleop device 'joystick'; valid devices: keyboard, replay"):
        TeleopAgent.from_device("joystick", task="GalbotG1-PickCube-Teleop-v0")


class _Transport:
    def __init__(self, frames):
        self.frames, self.opened, self.closed = list(frames), False, False

    def open(self):
        self.opened = True

    def read(self):
        return self.frames.pop(0) if self.frames else None

    def close(self):
        self.closed = True


def test_unsupported_task_fails_before_the_transport_opens():
    from newton_lab.agents.teleop import TeleopAgent

    transport = _Transport([])
    with pytest.raises(ValueError) as err:
        TeleopAgent.from_device("gp001", task="GalbotG1-Reach-v0", transport=transport)
    msg = str(err.value)
    assert "cannot drive GalbotG1-Reach-v0 (it has no teleop contract)" in msg
    assert "GalbotG1-PickCube-Teleop-v0" in msg and "\n" not in msg
    assert not transport.opened
    with pytest.raises(ValueError, match="needs the mobile_full_body contract"):
        TeleopAgent.from_device("spacemouse", task="GalbotG1-SortToShelf-v0")


def test_gp001_device_keeps_only_the_newest_frame():
    dev = Gp001Device(_Transport([]))
    for v in (0.1, 0.2, 0.3):
        dev.ingest(_raw(_axes(a0=v)))
    frame = dev.poll()
    assert frame.base_twist[0] == pytest.approx(0.3) and dev.frames.dropped == 2
    assert dev.poll() is None


def test_gp001_without_the_vendor_driver_says_so():
    from newton_lab.agents.teleop import TeleopAgent

    with pytest.raises(ValueError, match="vendor driver remote_control_lite is not installed"):
        TeleopAgent.from_device("gp001", task="GalbotG1-PickCube-Teleop-v0")


@pytest.mark.parametrize("name, package", [("spacemouse", "hidapi"), ("gamepad", "evdev")])
def test_optional_hid_devices_fail_in_one_line(name, package):
    from newton_lab.agents.teleop import TeleopAgent

    try:
        __import__("hid" if name == "spacemouse" else "evdev")
        pytest.skip(f"{package} is installed here")
    except ImportError:
        pass
    with pytest.raises(ValueError, match=f"{name}: the {package} package is not installed"):
        TeleopAgent.from_device(name, task="GalbotG1-PickCube-Teleop-v0")


def _keyboard(text: str) -> tuple[KeyboardDevice, int]:
    r, w = os.pipe()
    os.write(w, text.encode())
    os.close(w)
    dev = KeyboardDevice(r)
    dev.start()
    dev.resume()
    return dev, r


def _wait(pred, timeout=5.0):
    import time

    t0 = time.time()
    while not pred() and time.time() - t0 < timeout:
        time.sleep(0.01)
    return pred()


def test_keyboard_jogs_toggles_and_ends_on_done():
    dev, r = _keyboard("iiij rr u\x1b[A\x1b[Aqtnope\ndone\nkeep\n")
    assert _wait(dev.exit_requested)
    frame = dev.poll()
    assert frame.tcp_offset["left"][:3].tolist() == pytest.approx([0.03, 0.01, 0.02])
    assert frame.tcp_offset["left"][3] == pytest.approx(np.radians(5.0))
    assert frame.gripper_open["left"] is True  # toggled twice (two spaces)
    assert frame.base_twist == pytest.approx((0.1, 0.0, 0.1)) and frame.body_height == pytest.approx(0.02)
    assert dev.message == "episode ended: review it"
    dev.pause()
    from newton_lab.agents.teleop.session import read_line

    assert read_line(r) == "keep"  # nothing after "done" was read by the device
    dev.close()
    os.close(r)
    for key in "nope\n":
        dev.handle_key(key)
    assert dev.message == "unknown command 'nope'; type done to end the episode"


def test_review_prompt_answers_and_end_of_input():
    def answer(text):
        r, w = os.pipe()
        os.write(w, text.encode())
        os.close(w)
        out = io.StringIO()
        try:
            return review_demo(r, out), out.getvalue()
        finally:
            os.close(r)

    choice, text = answer("maybe\nk\n")
    assert choice == "keep"  # the unknown answer is refused and asked again, then "k" keeps
    assert text == (
        "\nkeep / drop / exit? 'maybe' is not an answer; type keep (k), drop (d) or exit (e)\n\nkeep / drop / exit? "
    )
    assert answer("drop\n")[0] == "drop"
    assert answer("q\n")[0] == "exit"
    assert answer("")[0] == "exit"


def test_teleop_task_has_the_operator_cameras_and_does_not_end_on_success():
    from newton_lab import tasks  # noqa: F401
    from newton_lab.task_api.registry import lookup

    cfg = lookup("GalbotG1-PickCube-Teleop-v0").make_cfg()
    assert {k: (c.width, c.height, c.data) for k, c in cfg.cameras.items()} == {
        "left_wrist": (640, 480, ("rgb",)),
        "front_head": (640, 480, ("rgb",)),
    }
    assert cfg.terminate_on_success is False
    pick = lookup("GalbotG1-PickCube-v0").make_cfg()
    assert cfg.actions == pick.actions
    # the same success logic: the same generic terms with the same parameters, before they are compiled
    assert (
        lookup("GalbotG1-PickCube-Teleop-v0").cfg().phase_success == lookup("GalbotG1-PickCube-v0").cfg().phase_success
    )


# ---------------------------------------------------------------- real physics (CPU)
@pytest.fixture(scope="module")
def expert_demo(tmp_path_factory):
    """One PickCube expert demo (seed 0, no randomisation, no cameras)."""
    from newton_lab.agents import PlannerAgent
    from newton_lab.envs import make_env

    env = make_env("GalbotG1-PickCube-v0", num_envs=1, device="cpu", seed=0, cameras=False)
    path = tmp_path_factory.mktemp("teleop") / "expert.hdf5"
    ref = env.collect(agent=PlannerAgent.from_task(env.task_id), episodes=1, path=path, progress=False)
    assert ref["successes"] == 1
    return path


@pytest.mark.parametrize("mode", ["actions", "tcp"])
def test_replay_device_redrives_an_expert_demo_to_success(expert_demo, mode):
    """Recorded joint targets, or the recorded TCP path through the agent's IK, on a new env with the same seed."""
    from newton_lab.agents.teleop import TeleopAgent
    from newton_lab.datasets.storage import read_episode
    from newton_lab.envs import make_env

    steps = len(read_episode(expert_demo, 0)["actions"])
    env = make_env("GalbotG1-PickCube-v0", num_envs=1, device="cpu", seed=0, cameras=False)
    agent = TeleopAgent.from_device("replay", task=env.task_id, path=expert_demo, mode=mode)
    summary = env.evaluate(agent=agent, episodes=1, max_steps=steps + 20, progress=False)
    assert summary["success_rate"] == 1.0 and summary["termination_reasons"] == {"success": 1}
    assert summary["episode_lengths"] == [steps]
    assert agent.latency()["frames"] == steps
    assert agent.jog_error() < 1e-3 if mode == "tcp" else agent.jog_error() == 0.0


def test_review_loop_keeps_drops_and_exits(expert_demo, tmp_path):
    """keep -> one successful demo; drop -> still one; end of input -> nothing added (a replayed operator)."""
    from newton_lab.agents.teleop import TeleopAgent, teleop_session
    from newton_lab.datasets import DatasetRef
    from newton_lab.envs import make_env

    env = make_env("GalbotG1-PickCube-Teleop-v0", num_envs=1, device="cpu", seed=0, cameras=False)
    path = tmp_path / "teleop.zarr"
    for answers, kept in (("keep\n", 1), ("drop\nexit\n", 1), ("", 1)):
        agent = TeleopAgent.from_device("replay", task=env.task_id, path=expert_demo)
        r, w = os.pipe()
        os.write(w, answers.encode())
        os.close(w)
        out = io.StringIO()
        try:
            teleop_session(env, agent, path=path, realtime=False, fd=r, out=out, keep=1)
        finally:
            os.close(r)
            agent.close()
        ref = DatasetRef.open(path)
        assert ref.num_demos == kept, out.getvalue()
        assert "ended by user_exit" in out.getvalue()
    info = ref.info()
    assert info["num_demos"] == 1
    assert [p.operation for p in ref.provenance] == ["teleop", "teleop", "drop", "teleop", "drop", "teleop", "drop"]


def test_tcp_jog_moves_each_joint_at_most_005_rad_per_step(pick_env):
    """A long jump of the jog target is reached through joint targets that move at most ``max_joint_step``
    (0.05 rad) per control step, as the expert's waypoints do; they then settle on the IK solution."""
    import warp as wp

    from newton_lab.agents.teleop.jog import TcpJog

    env = pick_env
    env.reset()
    jog = TcpJog(env, "left")
    assert jog.max_joint_step == 0.05
    start = jog(env, np.zeros(4)).copy()  # the start pose: no motion
    arm_q = wp.to_torch(env.state.joint_q).view(env.num_envs, -1)[:, env.joints.coords(spec.LEFT_ARM_JOINTS)]
    np.testing.assert_allclose(start, arm_q.cpu().numpy(), atol=0.05)
    commands = [start]
    target = np.array([0.12, -0.10, 0.10, 0.6])  # 18 cm and 34 degrees of yaw away
    for _ in range(80):
        commands.append(jog(env, target).copy())
    steps = np.abs(np.diff(np.stack(commands), axis=0))  # (80, N, 7)
    assert steps.max() <= 0.05 + 1e-12
    np.testing.assert_allclose(steps[0].max(axis=1), 0.05)  # a long jump: every row's first step is clipped
    assert steps[-5:].max() == 0.0  # arrived: the command is the IK solution and stays there
    assert jog.error < 5e-3
