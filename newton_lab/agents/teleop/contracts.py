"""Teleop contracts (which joint groups an operator drives) and the mapper from a ``TeleopFrame`` to a task's
action columns (the reference platform's teleop contracts, twist -> wheels mixing and body-height mapping).

A task declares its contract (``TaskSpec.teleop``); a device declares the contracts it can drive. The mapper
writes only the columns the task's action layout has, so one contract serves every task whose columns it
covers (e.g. ``mobile_full_body`` drives the coherent SortToShelf task, which has no right arm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ...robots.binding import RobotBinding
from ...robots.mecanum import twist_to_wheels_torch
from ...task_api.registry import list_tasks, lookup
from .frames import TeleopFrame

CONTRACTS: dict[str, tuple[str, ...]] = {
    "left_arm_manipulation": ("left_arm", "left_gripper"),
    "dual_arm": ("left_arm", "right_arm", "left_gripper", "right_gripper"),
    "mobile_full_body": ("base", "legs", "left_arm", "right_arm", "left_gripper", "right_gripper"),
}
"""Contract name -> the joint groups it drives (the robot's ``joint_groups``; on the G1 4 + 5 + 7 + 7 + 1 + 1 = 25
columns for the full body)."""
NO_FRAME_POLICIES = ("hold", "zero")
"""What a joint gets when no frame (or a frame without it) names a target: its current target, or 0."""


def teleop_tasks(contracts: Sequence[str] | None = None) -> dict[str, str]:
    """Registered task id -> contract, for the tasks that declare one of ``contracts`` (all when ``None``)."""
    out = {}
    for task_id in list_tasks():
        contract = lookup(task_id).teleop
        if contract is not None and (contracts is None or contract in contracts):
            out[task_id] = contract
    return out


def check_task(task_id: str, device: str, contracts: Sequence[str]) -> str:
    """The contract of ``task_id`` if ``device`` drives it; else one line naming the tasks it does drive."""
    contract = lookup(task_id).teleop
    if contract not in contracts:
        supported = ", ".join(teleop_tasks(contracts)) or "none"
        why = "has no teleop contract" if contract is None else f"needs the {contract} contract"
        raise ValueError(f"teleop device {device!r} cannot drive {task_id} (it {why}); tasks it drives: {supported}")
    return contract


def leg_targets(step: float, robot: RobotBinding) -> np.ndarray:
    """Leg joint targets for body-height step ``step`` [rad] (``robot.leg_lift``; the G1's: legs 1..5 at
    (s, 3s, 2s, 0, 0)) within the teleop clamps of ``robot`` (the env's)."""
    robot = RobotBinding.required(robot, "leg_targets")
    legs = np.asarray(robot.leg_lift(step), dtype=np.float64)
    for i, name in enumerate(robot.leg_joints):
        lo, hi = robot.teleop_leg_clamps.get(name, (-np.inf, np.inf))
        legs[i] = min(max(legs[i], lo), hi)
    return legs


def check_mapping(contract: str, no_frame_policy: str) -> None:
    """A known teleop ``contract`` and ``no_frame_policy``, or a one-line ``ValueError`` naming the valid ones."""
    if contract not in CONTRACTS:
        raise ValueError(f"unknown teleop contract {contract!r}; valid: {', '.join(CONTRACTS)}")
    if no_frame_policy not in NO_FRAME_POLICIES:
        raise ValueError(f"no_frame_policy {no_frame_policy!r} is unknown; use one of {', '.join(NO_FRAME_POLICIES)}")


class FrameMapper:
    """``TeleopFrame`` -> a full (num_envs, action_dim) action for one contract. Every row gets the same
    command (one operator); ``rows`` limits it to some rows (the others keep ``current``). ``robot``: the env's
    (``env.robot``: joint groups, gripper range, wheel gains, leg lift)."""

    def __init__(
        self,
        contract: str,
        action_joint_names: Sequence[str],
        *,
        robot: RobotBinding,
        no_frame_policy: str = "hold",
        twist_scale: float = 1.0,
    ):
        check_mapping(contract, no_frame_policy)
        self.contract, self.no_frame_policy, self.twist_scale = contract, no_frame_policy, float(twist_scale)
        self.robot = RobotBinding.required(robot, "FrameMapper")
        names, groups = list(action_joint_names), self.robot.joint_groups
        self.columns = {g: [names.index(j) for j in groups[g] if j in names] for g in CONTRACTS[contract]}
        """Action columns of each driven group that the task has (a group the task lacks maps to [])."""

    def __call__(
        self, frame: TeleopFrame | None, current: torch.Tensor, arm_targets: dict | None = None
    ) -> torch.Tensor:
        """The action for ``frame`` given the ``current`` (N, A) targets. ``arm_targets`` (arm -> (7,) [rad])
        overrides ``frame.arm_joints`` (the agent's IK of a Cartesian jog)."""
        out = current.clone() if self.no_frame_policy == "hold" else torch.zeros_like(current)
        frame = frame or TeleopFrame()
        arms = {**frame.arm_joints, **(arm_targets or {})}
        for arm in ("left", "right"):
            cols = self.columns.get(f"{arm}_arm", [])
            if cols and arm in arms:
                out[:, cols] = torch.as_tensor(np.asarray(arms[arm], dtype=np.float32)[: len(cols)], device=out.device)
            cols = self.columns.get(f"{arm}_gripper", [])
            if cols:  # a gripper is commanded every step: open unless the frame closes it
                opened = frame.gripper_open.get(arm, True)
                out[:, cols] = self.robot.gripper_open if opened else self.robot.gripper_closed
        cols = self.columns.get("base", [])
        if cols:
            vx, vy, wz = (0.0, 0.0, 0.0) if frame.base_twist is None else frame.base_twist
            s = self.twist_scale
            twist = torch.tensor([[vx * s, vy * s, wz * s]], dtype=torch.float32, device=out.device)
            out[:, cols] = twist_to_wheels_torch(twist, self.robot.wheel_gains)[0, : len(cols)]
        cols = self.columns.get("legs", [])
        if cols and frame.body_height is not None:
            legs = leg_targets(frame.body_height, self.robot)
            out[:, cols] = torch.as_tensor(legs[: len(cols)], dtype=out.dtype, device=out.device)
        return out
