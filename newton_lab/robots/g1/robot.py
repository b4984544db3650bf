"""The G1's binding: its facts (``spec``), model builder (``model``), kinematics, mecanum gains and camera
geometry (``cameras``) as one ``RobotBinding`` named ``g1``, the robot every task config names by default.

``robots.registry.robot_binding("g1")`` imports and registers it on the first look-up; code outside ``robots/`` and
the G1's own task configs reaches the G1 only through that binding (``env.robot``).
"""

from __future__ import annotations

from ..binding import Arm, RobotBinding
from . import cameras, spec
from .kinematics import TcpKinematics
from .mecanum import wheel_gains
from .model import build_g1

GROUP_KINDS: dict[str, tuple[str, ...]] = {
    "base": ("velocity",),
    "legs": ("absolute", "relative"),
    "left_arm": ("absolute", "relative"),
    "right_arm": ("absolute", "relative"),
    "head": ("absolute", "relative"),
    "left_gripper": ("binary", "absolute", "relative"),
    "right_gripper": ("binary", "absolute", "relative"),
}
"""The kinds that drive each joint group: the base's columns are wheel speeds the base un-mixes, every other
group has position drives (a velocity target would not reach them)."""

G1 = RobotBinding(
    name="g1",
    joint_groups=spec.JOINT_GROUPS,
    group_kinds=GROUP_KINDS,
    arms={
        "left": Arm(
            joints=spec.LEFT_ARM_JOINTS,
            gripper=spec.LEFT_GRIPPER_JOINT,
            end_effector=spec.END_EFFECTOR_LINK["left"],
            fingers=spec.GRIPPER_FINGER_JOINTS[:2],
        ),
        "right": Arm(
            joints=spec.RIGHT_ARM_JOINTS,
            gripper=spec.RIGHT_GRIPPER_JOINT,
            end_effector=spec.END_EFFECTOR_LINK["right"],
            fingers=spec.GRIPPER_FINGER_JOINTS[2:],
        ),
    },
    default_arm=spec.DEFAULT_ARM,
    base_planar_joints=spec.BASE_PLANAR_JOINTS,
    base_wheel_joints=spec.BASE_WHEEL_JOINTS,
    wheel_gains=wheel_gains(),
    leg_joints=spec.LEG_JOINTS,
    leg_lift=spec.leg_lift,
    teleop_leg_clamps=spec.TELEOP_LEG_CLAMPS,
    tcp_offset_pos=spec.TCP_OFFSET_POS,
    tcp_offset_quat=spec.TCP_OFFSET_QUAT,
    top_down_tcp_quat=spec.TOP_DOWN_TCP_QUAT,
    gripper_open=spec.GRIPPER_OPEN,
    gripper_closed=spec.GRIPPER_CLOSED,
    finger_travel_per_rad=spec.FINGER_TRAVEL_PER_RAD,
    fingertip_reach=spec.FINGERTIP_REACH,
    nav_max_speed=spec.NAV_MAX_SPEED,
    nav_success_radius=spec.NAV_SUCCESS_RADIUS,
    camera_mounts=spec.CAMERA_MOUNTS,
    camera_clipping=spec.CAMERA_CLIPPING,
    camera_resolution=(cameras.MIN_RESOLUTION, cameras.MAX_RESOLUTION),
    camera_intrinsics=cameras.intrinsics,
    camera_rays=cameras.pinhole_rays,
    link_groups=tuple(name for name, _ in cameras.LINK_GROUPS),
    link_group=cameras.link_group,
    hidden_link_groups=cameras.hidden_link_groups,
    build=build_g1,
    kinematics=TcpKinematics,
)
"""The Galbot G1 (``robot_binding("g1")``)."""
