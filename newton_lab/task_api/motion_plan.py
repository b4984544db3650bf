"""Motion plans: ordered TCP / joint / gripper steps, declared in YAML or Python by each task.

A target resolves per row at reset from live poses: ``AssetTarget`` (an entity's position + offset),
``WorldTarget`` (env-frame or base-frame point) or any callable ``(poses) -> (R, 3)`` where ``poses``
maps entity names and ``"tcp"`` / ``"base"`` to (R, 7) arrays and ``"command"`` to the task command
(an ``AssetTarget("command")`` reaches a commanded position). No quaternion means the top-down TCP.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import yaml


@dataclass(frozen=True)
class AssetTarget:
    asset: str
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Added to the asset's position (env frame) [m]."""

    def resolve(self, poses: dict[str, np.ndarray]) -> np.ndarray:
        return poses[self.asset][:, :3] + np.asarray(self.offset, dtype=np.float64)


@dataclass(frozen=True)
class WorldTarget:
    pos: tuple[float, float, float]
    frame: str = "world"
    """``world`` (env frame) or ``base`` (relative to the robot base pose)."""

    def resolve(self, poses: dict[str, np.ndarray]) -> np.ndarray:
        p = np.broadcast_to(np.asarray(self.pos, dtype=np.float64), poses["base"][:, :3].shape).copy()
        if self.frame == "base":
            base = poses["base"]
            yaw = yaw_of(base[:, 3:7])
            c, s = np.cos(yaw), np.sin(yaw)
            x, y = p[:, 0].copy(), p[:, 1].copy()
            p[:, 0] = base[:, 0] + c * x - s * y
            p[:, 1] = base[:, 1] + s * x + c * y
            p[:, 2] = base[:, 2] + p[:, 2]
        return p


@dataclass(frozen=True, kw_only=True)
class MotionStep:
    name: str
    target: AssetTarget | WorldTarget | Callable[[dict], np.ndarray] | None = None
    quat: tuple[float, float, float, float] | Callable[[dict], np.ndarray] | None = None
    """TCP orientation, xyzw (or a callable ``(poses) -> (R, 4)``); ``None`` = top-down."""
    align_yaw: str | None = None
    """Turn the top-down TCP about z to match this asset's yaw (modulo 90 deg)."""
    joints: tuple[float, ...] | None = None
    """Joint-space target of the arm (7) [rad]; bypasses IK."""
    gripper_open: bool = True
    hold: int = 1
    """Frames the command is repeated (gripper steps use e.g. 25)."""
    linear: int = 1
    """Straight-line TCP move: the segment from the previous TCP target is split into this many IK targets
    (1 = plain joint-space interpolation, which can bow the TCP path near obstacles)."""
    max_joint_step: float | None = None
    """This step's largest joint move per control step [rad] (``None``: the plan's): a slow final approach."""
    settle: bool = True
    """Hold the target for the plan's settle frames once there (``False``: the next step starts on arrival, e.g. after
    a slow approach that leaves nothing to settle)."""


@dataclass(frozen=True, kw_only=True)
class MotionPlan:
    steps: tuple[MotionStep, ...]
    max_joint_step: float = 0.03
    """Largest joint move per control step [rad]."""
    settle_steps: int = 12
    """Most extra frames each named target is held (the reference's 12). The hold ends as soon as every arm joint is
    within ``settle_tolerance`` of the target, except around the gripper's opening: in the step before it and in the
    step that opens it, the target is held the full frames. A step with ``settle=False`` holds none."""
    settle_tolerance: float = 0.01
    """Arm joint error [rad] at which a target counts as reached and its settle frames end (0: always the full
    ``settle_steps``). Still frames are frames a policy cannot place: one observation is followed by "hold" and, a
    few frames later, by the next move; state policies trained on experts with fewer of them stack and place far more
    often (benchmarks history, "StackCube: the still frames" and "the last 2 cm lowered slowly")."""
    position_tolerance: float = 0.035
    """IK solutions farther than this from the target mark the row's plan as failed [m]."""
    orientation_tolerance: float = 0.15
    arm: str = "left"
    extra: dict[str, Any] = field(default_factory=dict)


def yaw_of(quat_xyzw: np.ndarray) -> np.ndarray:
    """Yaw [rad] of xyzw quaternions (..., 4) -> (...)."""
    q = np.asarray(quat_xyzw, dtype=np.float64)
    x, y, z, w = (q[..., i] for i in range(4))
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _step_from_dict(d: dict) -> MotionStep:
    known = {"name", "target", "quat", "align_yaw", "joints", "gripper", "hold", "linear", "max_joint_step", "settle"}
    unknown = set(d) - known
    if unknown:
        raise ValueError(f"motion step {d.get('name')!r} has unknown keys {sorted(unknown)}; valid: {sorted(known)}")
    target = None
    t = d.get("target")
    if t is not None:
        if "asset" in t:
            target = AssetTarget(t["asset"], tuple(t.get("offset", (0.0, 0.0, 0.0))))
        elif "pos" in t:
            target = WorldTarget(tuple(t["pos"]), t.get("frame", "world"))
        else:
            raise ValueError(f"motion step {d.get('name')!r}: target needs 'asset' or 'pos'")
    gripper = d.get("gripper", "open")
    if gripper not in ("open", "closed"):
        raise ValueError(f"motion step {d.get('name')!r}: gripper must be 'open' or 'closed', got {gripper!r}")
    return MotionStep(
        name=d["name"],
        target=target,
        quat=tuple(d["quat"]) if d.get("quat") else None,
        align_yaw=d.get("align_yaw"),
        joints=tuple(d["joints"]) if d.get("joints") else None,
        gripper_open=gripper == "open",
        hold=int(d.get("hold", 1)),
        linear=max(1, int(d.get("linear", 1))),
        max_joint_step=float(d["max_joint_step"]) if d.get("max_joint_step") else None,
        settle=bool(d.get("settle", True)),
    )


def plan_from_yaml(text: str) -> MotionPlan:
    """Parse a YAML motion plan (keys: max_joint_step, settle_steps, settle_tolerance, position_tolerance,
    orientation_tolerance, arm, steps: [{name, target: {asset, offset} | {pos, frame}, quat, joints,
    gripper: open|closed, hold, linear, max_joint_step, settle}])."""
    data = yaml.safe_load(text)
    steps = tuple(_step_from_dict(s) for s in data.pop("steps"))
    return MotionPlan(steps=steps, **data)
