"""Teleop contracts (which joint groups an operator drives) and the mapper from a ``TeleopFrame`` to a task's
action columns (reference facts §2.2 "Teleop contracts", §2.3 twist -> wheels, §1.2 body-height mapping).

A task declares its contract (``TaskSpec.teleop``); a device declares the contracts it can drive. The mapper
writes only the columns the task's action layout has, so one contract serves every task whose columns it
covers (e.g. ``mobile_full_body`` drives the coherent SortToShelf task, which has no right arm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ...robots.g1 import spec
from ...robots.g1.packers import base_twist_to_wheel_velocities
from ...task_api.registry import list_tasks, lookup
from .frames import TeleopFrame

CONTRACTS: dict[str, tuple[str, ...]] = {
    "left_arm_manipulation": ("left_arm", "left_gripper"),
    "dual_arm": ("left_arm", "right_arm", "left_gripper", "right_gripper"),
    "mobile_full_body": ("base", "legs", "left_arm", "right_arm", "left_gripper", "right_gripper"),
}
"""Contract name -> the joint groups it drives (4 + 5 + 7 + 7 + 1 + 1 = 25 columns for the full body)."""
GROUP_JOINTS: dict[str, tuple[str, ...]] = {
    "base": spec.BASE_WHEEL_JOINTS, "legs": spec.LEG_JOINTS,
    "left_arm": spec.LEFT_ARM_JOINTS, "right_arm": spec.RIGHT_ARM_JOINTS,
    "left_gripper": (spec.LEFT_GRIPPER_JOINT,), "right_gripper": (spec.RIGHT_GRIPPER_JOINT,),
}
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


def leg_targets(step: float) -> np.ndarray:
    """Legs 1..5 for body-height step ``step`` [rad]: (s, 3s, 2s, 0, 0) with the teleop clamps."""
    legs = np.asarray(spec.leg_lift(step), dtype=np.float64)
    for i, name in enumerate(spec.LEG_JOINTS):
        lo, hi = spec.TELEOP_LEG_CLAMPS.get(name, (-np.inf, np.inf))
        legs[i] = min(max(legs[i], lo), hi)
    return legs


class FrameMapper:
    """``TeleopFrame`` -> a full (num_envs, action_dim) action for one contract. Every row gets the same
    command (one operator); ``rows`` limits it to some rows (the others keep ``current``)."""

    def __init__(self, contract: str, action_joint_names: Sequence[str], *, no_frame_policy: str = "hold",
                 twist_scale: float = 1.0):
        if contract not in CONTRACTS:
            raise ValueError(f"unknown teleop contract {contract!r}; valid: {', '.join(CONTRACTS)}")
        if no_frame_policy not in NO_FRAME_POLICIES:
            raise ValueError(f"no_frame_policy {no_frame_policy!r} is unknown; use one of {', '.join(NO_FRAME_POLICIES)}")
        self.contract, self.no_frame_policy, self.twist_scale = contract, no_frame_policy, float(twist_scale)
        names = list(action_joint_names)
        self.columns = {g: [names.index(j) for j in GROUP_JOINTS[g] if j in names] for g in CONTRACTS[contract]}
        """Action columns of each driven group that the task has (a group the task lacks maps to [])."""

    def __call__(self, frame: TeleopFrame | None, current: torch.Tensor, arm_targets: dict | None = None) -> torch.Tensor:
        """The action for ``frame`` given the ``current`` (N, A) targets. ``arm_targets`` (arm -> (7,) [rad])
        overrides ``frame.arm_joints`` (the agent's IK of a Cartesian jog)."""
        out = current.clone() if self.no_frame_policy == "hold" else torch.zeros_like(current)
        frame = frame or TeleopFrame()
        arms = {**frame.arm_joints, **(arm_targets or {})}
        for arm in ("left", "right"):
            cols = self.columns.get(f"{arm}_arm", [])
            if cols and arm in arms:
                out[:, cols] = torch.as_tensor(np.asarray(arms[arm], dtype=np.float32)[:len(cols)], device=out.device)
            cols = self.columns.get(f"{arm}_gripper", [])
            if cols:  # a gripper is commanded every step: open unless the frame closes it
                opened = frame.gripper_open.get(arm, True)
                out[:, cols] = spec.GRIPPER_OPEN if opened else spec.GRIPPER_CLOSED
        cols = self.columns.get("base", [])
        if cols:
            vx, vy, wz = (0.0, 0.0, 0.0) if frame.base_twist is None else frame.base_twist
            s = self.twist_scale
            wheels = base_twist_to_wheel_velocities(vx * s, vy * s, wz * s, num_envs=1, device=out.device)
            out[:, cols] = wheels[0, :len(cols)]
        cols = self.columns.get("legs", [])
        if cols and frame.body_height is not None:
            legs = leg_targets(frame.body_height)
            out[:, cols] = torch.as_tensor(legs[:len(cols)], dtype=out.dtype, device=out.device)
        return out
