"""The robot seam: every fact about a robot that the env, its buffers and kernels, the agents, Mimic and the viewers
use, as one ``RobotBinding``.

A task's config names its robot (``TaskCfg.robot``); the env looks it up (``robots.registry.robot_binding``) and
keeps it as ``env.robot``, so code past the robot's own package reads the robot only through that object. The G1's
binding is ``robots.g1.robot.G1``. This module is pure Python (no Warp, no Newton).

Units: [m], [rad], [s]; quaternions xyzw.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class JointIndex:
    """World-local coordinate / DOF indices of a builder's named joints, and its bodies' indices by name."""

    coord: dict[str, int]
    dof: dict[str, int]
    body: dict[str, int]

    @classmethod
    def from_builder(cls, builder: Any, *, merged: Mapping[str, Sequence[str]] | None = None) -> JointIndex:
        """Index ``builder``'s joints (a Newton ``ModelBuilder``) by the last part of their labels; a fixed joint
        has no coordinate of its own and is left out. ``merged`` names joints that the importer fused into one
        multi-DOF joint (e.g. a planar base's x / y / yaw slides and hinge into one D6): label -> the names of its
        coordinates, in order."""
        merged = merged or {}
        coord: dict[str, int] = {}
        dof: dict[str, int] = {}
        starts = list(builder.joint_q_start) + [builder.joint_coord_count]
        for j, label in enumerate(builder.joint_label):
            name = label.rsplit("/", 1)[-1]
            q0, qd0 = builder.joint_q_start[j], builder.joint_qd_start[j]
            if starts[j + 1] == q0:  # fixed joint: no coordinate of its own
                continue
            for i, sub in enumerate(merged.get(name, (name,))):
                coord[sub], dof[sub] = q0 + i, qd0 + i
        body = {label.rsplit("/", 1)[-1]: b for b, label in enumerate(builder.body_label)}
        return cls(coord=coord, dof=dof, body=body)


@dataclass(frozen=True)
class Arm:
    """One arm of the robot: its joints (in DOF order), the gripper's master joint and the link the TCP hangs on."""

    joints: tuple[str, ...]
    gripper: str
    """The gripper's master joint (its target runs from ``RobotBinding.gripper_open`` to ``gripper_closed``)."""
    end_effector: str
    """The body the TCP is fixed in (``RobotBinding.tcp_offset_pos`` / ``tcp_offset_quat`` from it)."""
    fingers: tuple[str, ...] = ()
    """The finger slides the gripper's master drives (``RobotBinding.finger_travel_per_rad`` of travel per radian);
    where they lag behind the master, something is between them (``TaskContext.finger_coords``). Two fingers are
    named in this order: the first closes toward the TCP's +y, the second toward -y (``kernels.context.
    finger_middle``)."""


@dataclass(frozen=True, kw_only=True)
class RobotBinding:
    """One robot, as the platform sees it: joint groups and the action kinds that drive them, arms and TCP, planar
    base and wheels, gripper range, camera mounts and pictures, and the hooks that build its model and kinematics."""

    name: str
    """Registry name (``TaskCfg.robot``, ``robots.registry``)."""
    joint_groups: Mapping[str, tuple[str, ...]]
    """Joint group -> its joints in action-column order (``ActionTermCfg.group``)."""
    group_kinds: Mapping[str, tuple[str, ...]]
    """Joint group -> the action kinds that can drive it (``ActionTermCfg.type``; ``velocity`` only for the wheels:
    every other group has position drives)."""
    arms: Mapping[str, Arm]
    """Arm name (``TaskCfg.arm``) -> its joints, gripper joint and TCP link."""
    default_arm: str
    base_planar_joints: tuple[str, ...]
    """The planar base's x, y [m] and yaw [rad] joints (world frame, velocity driven), contiguous coordinates."""
    base_wheel_joints: tuple[str, ...]
    """The wheel columns of the ``base`` action term (wheel speeds [rad/s]); empty for a robot without wheels."""
    wheel_gains: tuple[float, float]
    """Mecanum gains ``(lin, yaw)``: wheel [rad/s] per base [m/s] and per base yaw rate [rad/s]
    (``robots.mecanum``)."""
    leg_joints: tuple[str, ...]
    """The torso / leg joints, contiguous coordinates (``TaskContext.leg_coord`` is the first)."""
    leg_lift: Callable[[float], tuple[float, ...]]
    """Body-height step [rad] -> leg joint targets (teleop's body height)."""
    teleop_leg_clamps: Mapping[str, tuple[float, float]]
    """Leg joint -> (low, high) [rad] a teleop body-height command keeps within."""
    tcp_offset_pos: tuple[float, float, float]
    """TCP position in the end-effector link's frame [m]."""
    tcp_offset_quat: tuple[float, float, float, float]
    """TCP rotation in the end-effector link's frame (xyzw)."""
    top_down_tcp_quat: tuple[float, float, float, float]
    """The TCP orientation of a top-down grasp (xyzw), world frame: the planner's default."""
    gripper_open: float
    """Gripper master target when open [rad]."""
    gripper_closed: float
    """Gripper master target when closed [rad]."""
    finger_travel_per_rad: float
    """How far each finger slides inward per radian of the gripper master, with nothing between them [m/rad]."""
    fingertip_reach: float
    """How far the finger pads reach from the TCP along its approach axis (TCP +x, toward the fingertips) [m]."""
    nav_max_speed: float
    """Base speed limit of the nav agents [m/s]."""
    nav_success_radius: float
    """Distance to a nav goal that counts as reached [m]."""
    camera_mounts: Mapping[str, str]
    """Camera name -> the MJCF site its view follows (pinhole frame: looks along -z, +y up)."""
    camera_clipping: tuple[float, float]
    """Near and far clipping distances of every camera [m]."""
    camera_resolution: tuple[int, int]
    """Smallest and largest image side a camera accepts [px]."""
    camera_intrinsics: Callable[[int, int], Any]
    """``(width, height) -> 3x3 pinhole matrix K [px]`` (u right, v down, principal point at the centre)."""
    camera_rays: Callable[[int, int], Any]
    """``(width, height) -> (H, W, 1, 2, 3)`` camera-space rays of ``camera_intrinsics`` (origins on the near plane,
    unit directions), for Newton's ``SensorCamera``."""
    link_groups: tuple[str, ...]
    """Segmentation names of the robot's body groups (``robot/<group>``), in id order."""
    link_group: Callable[[str], str]
    """Body name -> its segmentation group (one of ``link_groups``)."""
    hidden_link_groups: Callable[[Collection[str]], tuple[str, ...]]
    """Joint groups an env's actions drive -> the link groups its cameras need not draw (out of every mount's view
    in that case; ``Cameras`` leaves their shapes out of the render, which changes no pixel and saves the rays'
    traversal of them)."""
    build: Callable[..., JointIndex]
    """``(builder, weld=None)``: add one robot at the origin to a Newton ``ModelBuilder`` (its planar base
    coordinates are its pose), with the joints named in ``weld`` welded at those values [rad | m]
    (``robots.weld``; joints coupled to a free one stay free), and return the builder's ``JointIndex``."""
    kinematics: Callable[..., Any]
    """``(n, *, device, arm) ->`` batched TCP kinematics of one arm for ``n`` problems: ``solve(q_seed, pos, quat,
    iterations=)`` (IK with ``newton.ik``) and ``tcp_poses(q)`` (FK), robot coordinates first in each row."""

    @staticmethod
    def required(robot: RobotBinding | None, user: str) -> RobotBinding:
        """``robot``, or a one-line ``ValueError`` saying ``user`` needs one: nothing falls back to a default
        robot."""
        if not isinstance(robot, RobotBinding):
            raise ValueError(
                f"{user} needs the robot it works for (robot=env.robot, or "
                f"newton_lab.robots.registry.robot_binding(name)), got {robot!r}"
            )
        return robot

    def arm(self, name: str) -> Arm:
        """The arm called ``name``; a one-line ``ValueError`` names the valid ones."""
        if name not in self.arms:
            raise ValueError(f"unknown arm {name!r}; valid arms of {self.name}: {sorted(self.arms)}")
        return self.arms[name]
