"""Navigation agents: drive the planar base with the 4-wheel velocity action (the reference platform's control law).

Every nav agent writes only the wheel columns and keeps the rest of the action at the current drive targets
(arm, legs and gripper hold), so it can drive a row of any task whose action space has a ``base`` term.
Base pose = the planar base coordinates (x, y [m], yaw [rad]), env frame.

The wheel speeds are the action (the reference's action space: datasets record them, policies learn them), so
an agent's twist becomes wheel speeds through the one mecanum formula (``robots.mecanum``, with the robot's gains,
``env.robot.wheel_gains``); the env's ``drive_base`` kernel applies the same formula's inverse because its base is
a planar joint without rollers.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ..robots.mecanum import twist_to_wheels_torch
from .base import BaseAgent


def wrap_angle(a: torch.Tensor) -> torch.Tensor:
    """Angles wrapped to [-pi, pi)."""
    return torch.remainder(a + math.pi, 2.0 * math.pi) - math.pi


def base_pose(env) -> torch.Tensor:
    """(num_envs, 3) planar base pose (x, y, yaw)."""
    return env.joints.positions(env.robot.base_planar_joints)


class BaseNavAgent(BaseAgent):
    """Shared machinery: per-row episode tracking, twist -> wheel columns. Subclasses implement ``twist``."""

    def setup(self, env) -> None:
        names, wheels = list(env.action_joint_names), env.robot.base_wheel_joints
        missing = [j for j in wheels if j not in names]
        if missing or not wheels:
            raise ValueError(
                f"env {env.task_id} has no wheel action columns {missing}; a nav agent needs a 'base' action term"
            )
        self._wheel_cols = [names.index(j) for j in wheels]

    def start(self, env, rows: np.ndarray, pose: torch.Tensor) -> None:
        """Per-row state for rows starting fresh (new episode, or handed over by a sequence / task flow)."""

    def twist(self, env, pose: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(vx, vy [m/s] base frame, wz [rad/s]) for every row."""
        raise NotImplementedError

    def act(self, env, env_ids=None) -> torch.Tensor:
        pose = base_pose(env)
        rows = self.fresh_rows(env, env_ids)
        if rows.size:
            self.start(env, rows, pose)
        vx, vy, wz = self.twist(env, pose)
        out = env.current_action()
        twist = torch.stack((vx, vy, wz), dim=1).to(out.device)
        out[:, self._wheel_cols] = twist_to_wheels_torch(twist, env.robot.wheel_gains)
        return out


class GoalNavAgent(BaseNavAgent):
    """Drive to ``goal`` (x, y) and turn to ``goal_yaw`` (the reference platform's control law).

    Heading toward the current target (``target``; the goal here), speed ``min(distance to goal, max_speed)``
    ramped by ``max_accel``; xy velocity zero inside ``success_radius``; yaw rate
    ``clamp(yaw_gain * wrap(goal_yaw - yaw), +-max_yaw_rate)`` zero inside ``yaw_tolerance``. With
    ``rotate_before_translate`` the base turns first and holds xy until the yaw is aligned, else it turns
    after reaching xy. ``goal_yaw=None`` never turns. ``done``: xy reached and yaw aligned. ``success_radius`` and
    ``max_speed`` left ``None`` are the robot's (``env.robot.nav_success_radius`` / ``nav_max_speed``).
    """

    def __init__(
        self,
        goal,
        goal_yaw: float | None = None,
        *,
        success_radius: float | None = None,
        yaw_tolerance: float = 0.03,
        max_speed: float | None = None,
        yaw_gain: float = 2.0,
        max_yaw_rate: float = 1.0,
        rotate_before_translate: bool = True,
        max_accel: float = 1.0,
        max_yaw_accel: float = 2.0,
    ):
        super().__init__()
        self.goal = tuple(float(v) for v in goal[:2])
        self.goal_yaw = None if goal_yaw is None else float(goal_yaw)
        self.success_radius = None if success_radius is None else float(success_radius)
        """Distance to the goal that counts as reached [m]; ``None``: the robot's."""
        self.yaw_tolerance = float(yaw_tolerance)
        self.max_speed = None if max_speed is None else float(max_speed)
        """Base speed limit [m/s]; ``None``: the robot's."""
        self.yaw_gain = float(yaw_gain)
        self.max_yaw_rate = float(max_yaw_rate)
        self.rotate_before_translate = bool(rotate_before_translate)
        self.max_accel = float(max_accel)
        """Speed ramp [m/s^2]: the commanded speed grows by at most this per second (a held object stays put)."""
        self.max_yaw_accel = float(max_yaw_accel)
        """Yaw-rate ramp [rad/s^2]: the commanded yaw rate changes by at most this per second."""

    def setup(self, env) -> None:
        super().setup(env)
        self._speed = torch.zeros(env.num_envs, device=env.torch_device)
        self._wz = torch.zeros(env.num_envs, device=env.torch_device)

    def start(self, env, rows, pose) -> None:
        r = torch.as_tensor(rows, device=env.torch_device)
        self._speed[r] = 0.0
        self._wz[r] = 0.0

    def target(self, env, pose: torch.Tensor) -> torch.Tensor:
        """(num_envs, 2) point the base heads for."""
        return torch.tensor(self.goal, device=env.torch_device).expand(env.num_envs, 2)

    def _errors(self, env, pose):
        goal = torch.tensor(self.goal, device=env.torch_device)
        dist = torch.linalg.norm(goal - pose[:, :2], dim=1)
        if self.goal_yaw is None:
            yaw_err = torch.zeros_like(dist)
        else:
            yaw_err = wrap_angle(self.goal_yaw - pose[:, 2])
        return dist, yaw_err

    def _radius(self, env) -> float:
        return env.robot.nav_success_radius if self.success_radius is None else self.success_radius

    def twist(self, env, pose):
        dist, yaw_err = self._errors(env, pose)
        xy_done = dist <= self._radius(env)
        yaw_ok = yaw_err.abs() <= self.yaw_tolerance
        wz = torch.clamp(self.yaw_gain * yaw_err, -self.max_yaw_rate, self.max_yaw_rate)
        wz = torch.where(yaw_ok, torch.zeros_like(wz), wz)
        speed = torch.clamp(dist, max=env.robot.nav_max_speed if self.max_speed is None else self.max_speed)
        if self.rotate_before_translate:
            speed = torch.where(yaw_ok, speed, torch.zeros_like(speed))
        else:
            wz = torch.where(xy_done, wz, torch.zeros_like(wz))
        speed = torch.where(xy_done, torch.zeros_like(speed), speed)
        dt = env.cfg.control_dt
        speed = torch.minimum(speed, self._speed + self.max_accel * dt)
        wz = torch.clamp(wz, self._wz - self.max_yaw_accel * dt, self._wz + self.max_yaw_accel * dt)
        self._speed, self._wz = speed, wz
        to_target = self.target(env, pose) - pose[:, :2]
        direction = to_target / torch.linalg.norm(to_target, dim=1, keepdim=True).clamp_min(1e-9)
        c, s = torch.cos(pose[:, 2]), torch.sin(pose[:, 2])
        vx = (c * direction[:, 0] + s * direction[:, 1]) * speed  # world -> base frame
        vy = (-s * direction[:, 0] + c * direction[:, 1]) * speed
        return vx, vy, wz

    def done(self, env) -> torch.Tensor:
        dist, yaw_err = self._errors(env, base_pose(env))
        return (dist <= self._radius(env)) & (yaw_err.abs() <= self.yaw_tolerance)


class ProportionalNavAgent(GoalNavAgent):
    """Heads straight for the goal every step (the target is the goal)."""


class TrajectoryNavAgent(GoalNavAgent):
    """Follows straight-line waypoints from the row's start to the goal, ``waypoint_spacing`` [m] apart; a
    waypoint is passed within ``min(success_radius, waypoint_spacing)``."""

    def __init__(self, goal, goal_yaw: float | None = None, *, waypoint_spacing: float = 0.25, **kwargs):
        super().__init__(goal, goal_yaw, **kwargs)
        if waypoint_spacing <= 0:
            raise ValueError(f"waypoint_spacing must be > 0 [m], got {waypoint_spacing}")
        self.waypoint_spacing = float(waypoint_spacing)

    def setup(self, env) -> None:
        super().setup(env)
        self._start = torch.zeros(env.num_envs, 2, device=env.torch_device)
        self._index = torch.ones(env.num_envs, device=env.torch_device)

    def start(self, env, rows, pose) -> None:
        super().start(env, rows, pose)
        r = torch.as_tensor(rows, device=env.torch_device)
        self._start[r] = pose[r, :2]
        self._index[r] = 1.0

    def _waypoint(self, env, index: torch.Tensor) -> torch.Tensor:
        goal = torch.tensor(self.goal, device=env.torch_device)
        span = goal - self._start
        length = torch.linalg.norm(span, dim=1, keepdim=True)
        along = torch.clamp(index[:, None] * self.waypoint_spacing, max=length)
        return self._start + span / length.clamp_min(1e-9) * along

    def target(self, env, pose):
        tol = min(self._radius(env), self.waypoint_spacing)
        for _ in range(4):  # pass every waypoint already reached this step
            wpt = self._waypoint(env, self._index)
            passed = torch.linalg.norm(wpt - pose[:, :2], dim=1) <= tol
            final = torch.linalg.norm(wpt - torch.tensor(self.goal, device=env.torch_device), dim=1) < 1e-6
            step = passed & ~final
            if not bool(step.any()):
                break
            self._index = self._index + step.float()
        return self._waypoint(env, self._index)
