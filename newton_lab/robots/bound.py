"""A robot bound to a built scene: the robot half of the task context, the one action map, the drive limits.

:meth:`BoundRobot.from_layout` resolves, once, every robot index the env's kernels need, from the robot's facts
(``robots.binding.RobotBinding``: joint groups, arms, TCP, gripper values) and the scene's joint index
(``envs.scene.SceneLayout``: ``joints.coord / dof / body``, ``robot_coords``, ``coords_per_world``,
``dofs_per_world`` and the finalized ``model``):

* :class:`RobotContext` - base / leg / wheel / gripper coordinates, TCP body + offset, arm coordinates and
  ``robot_coords``; :meth:`RobotContext.fill` writes them into a ``kernels.context.TaskContext``.
* :class:`ActionMap` - action columns -> joint position targets / wheel speeds, one kind per column:
  ``absolute`` (target = a), ``relative`` (target = current target + a, kept within the joint's range),
  ``velocity`` (the base's wheel speeds [rad/s]) and ``binary`` (gripper master target, clipped to
  open .. closed). Each column's action is first scaled and clipped: ``clamp(scale * a, clip)``.
* :class:`DriveLimits` - the velocity limits the model carries in ``joint_velocity_limit`` (written by the robot's
  model builder, e.g. ``robots.g1.model.apply_spec_limits``), per coordinate, for the env's setpoint kernel.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import newton
import numpy as np
import torch
import warp as wp

from .binding import RobotBinding

ACTION_KINDS = ("absolute", "relative", "velocity", "binary")
"""Every action kind a column can have (``ActionTermCfg.type``)."""

UNSET_VELOCITY_LIMIT = newton.ModelBuilder.JointDofConfig().velocity_limit
"""Newton's default ``joint_velocity_limit`` (a joint without a declared limit)."""


def _first_coord(coord: dict[str, int], joints: Sequence[str], what: str) -> int:
    """The coordinate of ``joints[0]``, whose following joints must hold the following coordinates (a kernel
    reads them as one run)."""
    first = coord[joints[0]]
    if [coord[j] - first for j in joints] != list(range(len(joints))):
        raise ValueError(f"{what} joints {tuple(joints)} are not contiguous coordinates in the model")
    return first


@dataclass(frozen=True)
class RobotContext:
    """The robot's world-local indices every task term reads through ``TaskContext``."""

    robot_coords: int
    base_coord: int
    """``base_x`` (``base_y``, ``base_yaw`` follow)."""
    lift_coords: tuple[int, ...]
    """The joints that lift the upper body (``RobotBinding.leg_joints``), in order; empty without them."""
    wheel_coord: int
    """The first base wheel (the others follow); -1 without wheels."""
    wheel_count: int
    tcp_body: int
    tcp_offset_pos: tuple[float, float, float]
    tcp_offset_quat: tuple[float, float, float, float]
    gripper_coord: int
    gripper_open: float
    gripper_closed: float
    """The gripper master's open and closed values [rad]."""
    finger_coords: tuple[int, ...]
    finger_travel_per_rad: float
    fingertip_reach: float
    arm_coords: tuple[int, ...]

    @classmethod
    def from_layout(cls, robot: RobotBinding, layout: Any, arm: str) -> RobotContext:
        chosen = robot.arm(arm)
        coord = layout.joints.coord
        legs, planar, wheels = robot.leg_joints, robot.base_planar_joints, robot.base_wheel_joints
        base = _first_coord(coord, planar, "planar base")
        wheel = _first_coord(coord, wheels, "base wheel") if wheels else -1
        return cls(
            robot_coords=int(layout.robot_coords),
            base_coord=base,
            lift_coords=tuple(coord[j] for j in legs),
            wheel_coord=wheel,
            wheel_count=len(wheels),
            tcp_body=layout.joints.body[chosen.end_effector],
            tcp_offset_pos=robot.tcp_offset_pos,
            tcp_offset_quat=robot.tcp_offset_quat,
            gripper_coord=coord[chosen.gripper],
            gripper_open=float(robot.gripper_open),
            gripper_closed=float(robot.gripper_closed),
            finger_coords=tuple(coord[j] for j in chosen.fingers),
            finger_travel_per_rad=float(robot.finger_travel_per_rad),
            fingertip_reach=float(robot.fingertip_reach),
            arm_coords=tuple(coord[j] for j in chosen.joints),
        )

    def fill(self, ctx: Any) -> None:
        """Write the robot half into a ``TaskContext`` (its arrays on the current Warp device)."""
        ctx.robot_coords = self.robot_coords
        ctx.base_coord = self.base_coord
        ctx.lift_coords = wp.array(self.lift_coords, dtype=int) if self.lift_coords else wp.zeros(0, dtype=int)
        ctx.wheel_coord = self.wheel_coord
        ctx.wheel_count = self.wheel_count
        ctx.tcp_body = self.tcp_body
        ctx.tcp_offset = wp.transform(wp.vec3(*self.tcp_offset_pos), wp.quat(*self.tcp_offset_quat))
        ctx.gripper_coord = self.gripper_coord
        ctx.gripper_open = self.gripper_open
        ctx.gripper_closed = self.gripper_closed
        ctx.finger_coords = wp.array(self.finger_coords, dtype=int) if self.finger_coords else wp.zeros(0, dtype=int)
        ctx.finger_travel_per_rad = self.finger_travel_per_rad
        ctx.fingertip_reach = self.fingertip_reach
        ctx.arm_coords = wp.array(self.arm_coords, dtype=int)


@dataclass(frozen=True)
class ActionMap:
    """Action columns -> joints, in ``ActionTermCfg`` declaration order (per-column numpy arrays)."""

    joint_names: tuple[str, ...]
    kinds: tuple[str, ...]
    """Kind of each column (one of ``ACTION_KINDS``)."""
    terms: dict[str, slice]
    """Columns of each action term, by term name."""
    term_groups: dict[str, str]
    index: np.ndarray
    """Coordinate (position kinds) or DOF (velocity) of each column's joint, world-local (int32)."""
    scale: np.ndarray
    low: np.ndarray
    high: np.ndarray
    """Clip of the scaled action (float32): the term's clip, open .. closed for binary, else unbounded."""
    target_low: np.ndarray
    target_high: np.ndarray
    """Joint range that bounds a relative column's accumulated target (float32)."""
    wheel_col: int
    """First of the four wheel columns (wheel1..wheel4), -1 without a base term."""

    @property
    def dim(self) -> int:
        return len(self.joint_names)

    @classmethod
    def from_terms(cls, robot: RobotBinding, terms: Sequence[Any], layout: Any) -> ActionMap:
        """Columns of ``terms`` (``ActionTermCfg``) on the scene ``layout``; refuses unknown groups / kinds
        with a one-line ``ValueError``."""
        joints, cols = layout.joints, _Columns(robot)
        lower, upper = (
            np.asarray(a.numpy()[: layout.dofs_per_world], dtype=np.float32)
            for a in (layout.model.joint_limit_lower, layout.model.joint_limit_upper)
        )
        spans, groups, owner = {}, {}, {}
        for term in terms:
            kind = _check_term(robot, term)
            start = len(cols.names)
            for j in robot.joint_groups[term.group]:
                if j in owner:
                    raise ValueError(
                        f"joint {j!r} is in action terms {owner[j]!r} and {term.name!r}; list each joint group once"
                    )
                owner[j] = term.name
                d = joints.dof[j]
                cols.add(j, kind, d if kind == "velocity" else joints.coord[j], term, (lower[d], upper[d]))
            spans[term.name], groups[term.name] = slice(start, len(cols.names)), term.group
        base = [t.name for t in terms if t.group == "base"]
        return cols.build(spans, groups, spans[base[0]].start if base else -1)

    def ownership(self, phases: Sequence[Any], fixed_base: bool) -> tuple[np.ndarray, np.ndarray]:
        """``owned`` (phases, columns): which columns each phase commands (the others hold); ``base_free``
        (phases,): whether the phase may move the base. No phases: one phase owning every column."""
        owned = np.ones((max(len(phases), 1), max(self.dim, 1)), dtype=bool)
        base_free = np.full(max(len(phases), 1), not fixed_base, dtype=bool)
        for p, ph in enumerate(phases):
            if ph.action_groups is not None:
                for term, cols in self.terms.items():
                    owned[p, cols] = self.term_groups[term] in ph.action_groups
            base_free[p] = not ph.fixed_base
        return owned, base_free

    @cached_property
    def _held(self) -> dict[torch.device, tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """Per device, ``hold``'s absolute / binary columns, their joints' coordinates and scales as tensors, made
        once: a copy from the host's pageable memory to a GPU first waits for the GPU's queue, and PPO's delta
        targets read ``hold`` at every step."""
        return {}

    def hold(self, joint_target_q: torch.Tensor) -> torch.Tensor:
        """The action that keeps every column where it is: absolute / binary columns at their current position
        targets (``joint_target_q``: (num_envs, coords_per_world)), relative and velocity columns at 0."""
        dev = joint_target_q.device
        if dev not in self._held:
            cols = [c for c, k in enumerate(self.kinds) if k in ("absolute", "binary")]
            self._held[dev] = (
                torch.as_tensor(cols, dtype=torch.long, device=dev),
                torch.as_tensor(self.index[cols], dtype=torch.long, device=dev),
                torch.as_tensor(self.scale[cols], dtype=torch.float32, device=dev),
            )
        cols, coords, scale = self._held[dev]
        out = torch.zeros(joint_target_q.shape[0], self.dim, dtype=torch.float32, device=dev)
        if cols.numel():
            out[:, cols] = joint_target_q[:, coords].to(torch.float32) / scale
        return out


def _check_term(robot: RobotBinding, term: Any) -> str:
    """The term's kind, after checking its group and type (one-line errors naming the valid values)."""
    if term.group not in robot.joint_groups:
        raise ValueError(
            f"action term {term.name!r}: unknown group {term.group!r}; valid groups: {', '.join(robot.joint_groups)}"
        )
    if term.type not in ACTION_KINDS:
        raise ValueError(
            f"action term {term.name!r}: unknown type {term.type!r}; valid kinds: {', '.join(ACTION_KINDS)}"
        )
    kinds = robot.group_kinds[term.group]
    if term.type not in kinds:
        raise ValueError(
            f"action term {term.name!r}: type {term.type!r} does not drive group {term.group!r}; use {'|'.join(kinds)}"
        )
    return term.type


def _f32(values: list[float]) -> np.ndarray:
    return np.asarray(values, dtype=np.float32)


class _Columns:
    """Accumulates per-column values while an ``ActionMap`` is built."""

    def __init__(self, robot: RobotBinding):
        self.gripper_range = (robot.gripper_open, robot.gripper_closed)
        self.names, self.kinds, self.index, self.scale = [], [], [], []
        self.low, self.high, self.target_low, self.target_high = [], [], [], []

    def add(self, joint: str, kind: str, index: int, term: Any, joint_range: tuple[float, float]) -> None:
        lo, hi = term.clip if term.clip else (-np.inf, np.inf)
        if kind == "binary":
            lo, hi = self.gripper_range
        self.names.append(joint)
        self.kinds.append(kind)
        self.index.append(index)
        self.scale.append(float(term.scale))
        self.low.append(lo)
        self.high.append(hi)
        self.target_low.append(joint_range[0] if kind == "relative" else -np.inf)
        self.target_high.append(joint_range[1] if kind == "relative" else np.inf)

    def build(self, terms: dict[str, slice], groups: dict[str, str], wheel_col: int) -> ActionMap:
        return ActionMap(
            joint_names=tuple(self.names),
            kinds=tuple(self.kinds),
            terms=terms,
            term_groups=groups,
            index=np.asarray(self.index, dtype=np.int32),
            scale=_f32(self.scale),
            low=_f32(self.low),
            high=_f32(self.high),
            target_low=_f32(self.target_low),
            target_high=_f32(self.target_high),
            wheel_col=wheel_col,
        )


@dataclass(frozen=True)
class DriveLimits:
    """Per-coordinate velocity limits of the robot's position-driven joints, from the model."""

    max_rate: np.ndarray
    """(coords_per_world,) velocity limit [rad/s | m/s] of each coordinate, 0 where none (float32)."""
    coord_dof: np.ndarray
    """(coords_per_world,) DOF of each limited coordinate, -1 elsewhere (int32)."""
    dof_limited: np.ndarray
    """(dofs_per_world,) whether a DOF's velocity target comes from its rate-limited setpoint (bool)."""

    @classmethod
    def from_layout(cls, layout: Any) -> DriveLimits:
        model = layout.model
        limit = model.joint_velocity_limit.numpy()[: layout.dofs_per_world]
        mode = model.joint_target_mode.numpy()[: layout.dofs_per_world]
        position = (int(newton.JointTargetMode.POSITION), int(newton.JointTargetMode.POSITION_VELOCITY))
        max_rate = np.zeros(layout.coords_per_world, dtype=np.float32)
        coord_dof = np.full(layout.coords_per_world, -1, dtype=np.int32)
        dof_limited = np.zeros(layout.dofs_per_world, dtype=bool)
        for name, c in layout.joints.coord.items():
            d = layout.joints.dof[name]
            if limit[d] < UNSET_VELOCITY_LIMIT and mode[d] in position:
                max_rate[c], coord_dof[c], dof_limited[d] = limit[d], d, True
        return cls(max_rate=max_rate, coord_dof=coord_dof, dof_limited=dof_limited)

    @property
    def any(self) -> bool:
        return bool(self.dof_limited.any())


@dataclass(frozen=True)
class BoundRobot:
    """A robot on one built scene: ``robot`` (its facts), ``context`` (robot half of the task context), ``actions``
    (the action map), ``limits`` (drive velocity limits)."""

    robot: RobotBinding
    context: RobotContext
    actions: ActionMap
    limits: DriveLimits

    @classmethod
    def from_layout(
        cls, robot: RobotBinding, layout: Any, *, actions: Sequence[Any], arm: str | None = None
    ) -> BoundRobot:
        """Bind ``robot`` in ``layout`` (``envs.scene.SceneLayout``) with the task's action terms and arm (the
        robot's default arm when ``None``)."""
        return cls(
            robot=robot,
            context=RobotContext.from_layout(robot, layout, robot.default_arm if arm is None else arm),
            actions=ActionMap.from_terms(robot, actions, layout),
            limits=DriveLimits.from_layout(layout),
        )
