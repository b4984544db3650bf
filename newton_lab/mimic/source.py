"""Source demos for Mimic: per step target TCP poses (forward kinematics of the commanded arm joints),
gripper commands, object poses and the subtask signals that segment them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..datasets.states import state_tree
from ..datasets.storage import read_dataset_info, read_episodes
from ..robots.binding import RobotBinding
from ..task_api.mimic_cfg import MimicCfg


@dataclass
class SourceDemo:
    demo_id: int
    target_tcp: np.ndarray
    """(T, 7) commanded TCP pose per step."""
    gripper: np.ndarray
    """(T,) gripper command per step [rad]."""
    objects: dict[str, np.ndarray]
    """Entity name -> (T, 7) pose per step."""
    signal_edges: dict[str, int]
    """Signal name -> first step where it is on."""
    length: int

    def boundaries(self, cfg: MimicCfg, rng: np.random.Generator) -> list[int] | None:
        """Segment end indices (one per subtask, last = T) with the subtasks' random offsets; ``None``
        when the randomised segments are not strictly increasing."""
        ends = []
        for sub in cfg.subtasks:
            if sub.term_signal is None:
                ends.append(self.length)
            else:
                lo, hi = sub.term_offset_range
                ends.append(min(self.signal_edges[sub.term_signal] + int(rng.integers(lo, hi + 1)), self.length - 1))
        starts = [0] + ends[:-1]
        if any(e <= s for s, e in zip(starts, ends)):
            return None
        return ends


def load_sources(path: Path, cfg: MimicCfg, kinematics, *, task_id: str, robot: RobotBinding) -> list[SourceDemo]:
    """Successful demos of ``path`` that carry every signal ``cfg`` segments on; ``kinematics`` (the robot's,
    ``RobotBinding.kinematics``) turns their commanded arm joints into TCP poses. ``robot``: the env's
    (``env.robot``)."""
    robot = RobotBinding.required(robot, "load_sources")
    info = read_dataset_info(path)
    args = info["env_args"].get("newton_lab", {})
    names = args.get("action_joint_names", [])
    arm = robot.arm(cfg.arm)
    arm_joints = list(arm.joints)
    if not all(j in names for j in arm_joints):
        raise ValueError(f"{path}: actions do not hold the {cfg.arm} arm joints; Mimic needs arm joint-target actions")
    arm_cols = [names.index(j) for j in arm_joints]
    grip_name = arm.gripper
    grip_col = names.index(grip_name) if grip_name in names else None
    sources: list[SourceDemo] = []
    ids = [demo for demo in info["demo_ids"] if info["demos"][demo]["success"]]
    for demo, ep in zip(ids, read_episodes(path, ids, attrs=True)):
        signals = ep.get("datagen", {}).get("subtask_signals", {})
        missing = [s for s in cfg.signals if s not in signals]
        if missing:
            raise ValueError(
                f"{path} demo {demo} has no subtask signals {missing}: Mimic needs datasets written by "
                f"newton_lab env.collect (datagen/subtask_signals) for {task_id}; re-collect the source demos"
            )
        edges = {}
        for s in cfg.signals:
            on = np.nonzero(np.asarray(signals[s], dtype=bool))[0]
            if len(on) == 0:
                break
            edges[s] = int(on[0])
        if len(edges) < len(cfg.signals):
            continue  # a successful demo whose signal never fired cannot be segmented
        robot = state_tree(ep["states"], info["env_args"])["articulation"]["robot"]
        q = np.asarray(robot["joint_position"], dtype=np.float64)
        actions = np.asarray(ep["actions"], dtype=np.float64)
        q_cmd = q.copy()
        q_cmd[:, kinematics.arm_coords] = actions[:, arm_cols]
        tcp = np.concatenate(
            [kinematics.tcp_poses(q_cmd[i : i + kinematics.n]) for i in range(0, len(q), kinematics.n)]
        )
        grip = actions[:, grip_col] if grip_col is not None else np.zeros(len(actions))
        objects = {k: np.asarray(v, dtype=np.float64) for k, v in ep["datagen"]["object_poses"].items()}
        sources.append(SourceDemo(demo, tcp, grip, objects, edges, len(actions)))
    if not sources:
        raise ValueError(
            f"{path}: no successful source demo with the subtask signals {cfg.signals}; collect some first"
        )
    return sources
