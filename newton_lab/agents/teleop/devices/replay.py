"""``replay``: a recorded demo's actions played back as device frames, one per control step (the test driver,
and a way to re-drive a demo on another scene). When the demo's last frame has been sent the device asks to
end the episode (reason ``user_exit``), as an operator typing ``done`` would."""

from __future__ import annotations

import time

import numpy as np

from ....datasets.storage import list_demos, read_dataset_info, read_episode
from ....robots.g1 import spec
from ..frames import TeleopFrame
from .base import TeleopDevice


class ReplayDevice(TeleopDevice):
    """Plays ``demo`` (a demo id; default the first) of the dataset at ``path``: arm joint targets and gripper
    open / closed per recorded action row, mapped by the dataset's action joint names."""

    name = "replay"
    contracts = ("left_arm_manipulation", "dual_arm", "mobile_full_body")

    def __init__(self, path, demo: int | None = None):
        super().__init__()
        info = read_dataset_info(path)
        ids = list_demos(path)
        if not ids:
            raise ValueError(f"replay: {path} holds no demos; collect one first (newton-lab collect ...)")
        self.demo = ids[0] if demo is None else int(demo)
        self.actions = np.asarray(read_episode(path, self.demo)["actions"], dtype=np.float64)
        self.names = list(info["env_args"]["newton_lab"]["action_joint_names"])
        self.cursor = 0

    def reset(self) -> None:
        super().reset()
        self.cursor = 0

    def _frame(self, row: np.ndarray) -> TeleopFrame:
        col = {name: i for i, name in enumerate(self.names)}
        arms, grippers = {}, {}
        for arm, joints, gripper in (("left", spec.LEFT_ARM_JOINTS, spec.LEFT_GRIPPER_JOINT),
                                     ("right", spec.RIGHT_ARM_JOINTS, spec.RIGHT_GRIPPER_JOINT)):
            if all(j in col for j in joints):
                arms[arm] = row[[col[j] for j in joints]]
            if gripper in col:  # the recorded target: nearer open (0.0) or closed (1.2)
                grippers[arm] = bool(row[col[gripper]] < 0.5 * (spec.GRIPPER_OPEN + spec.GRIPPER_CLOSED))
        return TeleopFrame(timestamp=time.perf_counter(), arm_joints=arms, gripper_open=grippers, raw={"row": row})

    def poll(self) -> TeleopFrame | None:
        if self.cursor >= len(self.actions):
            self.request_exit()
            return None
        frame = self._frame(self.actions[self.cursor])
        self.cursor += 1
        return frame
