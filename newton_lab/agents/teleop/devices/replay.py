"""``replay``: a recorded demo played back as device frames, one per control step (the test driver, and a way to
re-drive a demo on another scene). ``mode="actions"`` sends the recorded joint targets; ``mode="tcp"`` sends the
recorded TCP path as a Cartesian jog from the episode's start pose (the agent's IK follows it, so the demo's
motion re-targets to another start posture). When the demo's last frame has been sent the device asks to end
the episode (reason ``user_exit``), as an operator typing ``done`` would."""

from __future__ import annotations

import time

import numpy as np

from ....datasets.storage import list_demos, read_dataset_info, read_episode
from ....robots.quaternions import quat_mul
from ....robots.registry import DEFAULT_ROBOT, robot_binding
from ..frames import TeleopFrame
from .base import TeleopDevice

REPLAY_MODES = ("actions", "tcp")


def tcp_offsets(tcp: np.ndarray) -> np.ndarray:
    """(T, 4) jog offsets (dx, dy, dz [m], dyaw [rad]) of recorded TCP poses (T, 7 xyzw) from the first one."""
    inv0 = np.tile(tcp[:1, 3:7] * np.array([-1.0, -1.0, -1.0, 1.0]), (len(tcp), 1))
    x, y, z, w = quat_mul(tcp[:, 3:7], inv0).T  # world-frame rotation since the start: near identity, so its
    out = np.zeros((len(tcp), 4))  # yaw is well defined (a top-down TCP's own yaw is not)
    out[:, :3] = tcp[:, :3] - tcp[0, :3]
    out[:, 3] = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return out


class ReplayDevice(TeleopDevice):
    """Plays ``demo`` (a demo id; default the first) of the dataset at ``path``: arm joint targets and gripper
    open / closed per recorded action row, mapped by the dataset's action joint names."""

    name = "replay"
    contracts = ("left_arm_manipulation", "dual_arm", "mobile_full_body")

    def __init__(self, path, demo: int | None = None, mode: str = "actions"):
        super().__init__()
        if mode not in REPLAY_MODES:
            raise ValueError(f"replay mode {mode!r} is unknown; use one of {', '.join(REPLAY_MODES)}")
        info = read_dataset_info(path)
        ids = list_demos(path)
        if not ids:
            raise ValueError(f"replay: {path} holds no demos; collect one first (newton-lab collect ...)")
        self.demo = ids[0] if demo is None else int(demo)
        episode = read_episode(path, self.demo)
        self.actions = np.asarray(episode["actions"], dtype=np.float64)
        self.names = list(info["env_args"]["newton_lab"]["action_joint_names"])
        self.robot = robot_binding(info["env_args"]["newton_lab"].get("robot", DEFAULT_ROBOT))
        """The robot that made the demo (its arms' joints and gripper range)."""
        self.mode, self.cursor = mode, 0
        if mode == "tcp":
            if "tcp_pose" not in episode["obs"]:
                raise ValueError(f"replay: demo {self.demo} of {path} has no obs/tcp_pose; use mode='actions'")
            self.jog_arms = ("left",)
            self.tcp_offsets = tcp_offsets(np.asarray(episode["obs"]["tcp_pose"], dtype=np.float64))

    def reset(self) -> None:
        super().reset()
        self.cursor = 0

    def _frame(self, row: np.ndarray) -> TeleopFrame:
        col = {name: i for i, name in enumerate(self.names)}
        arms, grippers = {}, {}
        half = 0.5 * (self.robot.gripper_open + self.robot.gripper_closed)
        for arm, limb in self.robot.arms.items():
            if all(j in col for j in limb.joints):
                arms[arm] = row[[col[j] for j in limb.joints]]
            if limb.gripper in col:  # the recorded target: nearer open (G1: 0.0) or closed (1.2)
                grippers[arm] = bool(row[col[limb.gripper]] < half)
        return TeleopFrame(timestamp=time.perf_counter(), arm_joints=arms, gripper_open=grippers, raw={"row": row})

    def poll(self) -> TeleopFrame | None:
        if self.cursor >= len(self.actions):
            self.request_exit()
            return None
        frame = self._frame(self.actions[self.cursor])
        if self.mode == "tcp":  # the pose the recorded action led to (obs are recorded before each step)
            offset = self.tcp_offsets[min(self.cursor + 1, len(self.tcp_offsets) - 1)]
            frame = TeleopFrame(timestamp=frame.timestamp, tcp_offset={"left": offset}, gripper_open=frame.gripper_open)
        self.cursor += 1
        return frame
