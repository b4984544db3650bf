"""Galbot G1: pure-data spec (joint groups, orders, postures, mounts). No Warp, no Newton.

Units: [m], [rad], [kg]. Quaternions xyzw. Joint values are for newton_lab's authored model
(``assets/g1/galbot_g1.xml``); where the authored kinematics differ from the reference robot, postures
keep the reference intent (same TCP pose / view) and are re-derived here, noted per constant.
"""

from __future__ import annotations

import math

ROBOT_NAME = "galbot_g1"
MJCF_FILE = "g1/galbot_g1.xml"

# ---------------------------------------------------------------- joint groups (explicit DOF orders)
BASE_WHEEL_JOINTS = ("wheel1_joint", "wheel2_joint", "wheel3_joint", "wheel4_joint")
LEG_JOINTS = tuple(f"leg_joint{i}" for i in range(1, 6))
LEFT_ARM_JOINTS = tuple(f"left_arm_joint{i}" for i in range(1, 8))
RIGHT_ARM_JOINTS = tuple(f"right_arm_joint{i}" for i in range(1, 8))
LEFT_GRIPPER_JOINT = "left_gripper_joint"
RIGHT_GRIPPER_JOINT = "right_gripper_joint"
HEAD_JOINTS = ("head_joint1", "head_joint2")
# Planar base (stands in for the mecanum rollers): world-frame x / y slides and yaw hinge.
BASE_PLANAR_JOINTS = ("base_x", "base_y", "base_yaw")
# Finger slides coupled to the gripper master joint (never commanded directly).
GRIPPER_FINGER_JOINTS = (
    "left_gripper_l_finger_joint",
    "left_gripper_r_finger_joint",
    "right_gripper_l_finger_joint",
    "right_gripper_r_finger_joint",
)

ALL_JOINT_NAMES = (
    BASE_PLANAR_JOINTS
    + BASE_WHEEL_JOINTS
    + LEG_JOINTS
    + HEAD_JOINTS
    + LEFT_ARM_JOINTS
    + RIGHT_ARM_JOINTS
    + (LEFT_GRIPPER_JOINT, RIGHT_GRIPPER_JOINT)
    + GRIPPER_FINGER_JOINTS
)
"""Every joint of the MJCF (34; the planar base's three count separately, as the env indexes them)."""

JOINT_GROUPS: dict[str, tuple[str, ...]] = {
    "base": BASE_WHEEL_JOINTS,
    "legs": LEG_JOINTS,
    "left_arm": LEFT_ARM_JOINTS,
    "right_arm": RIGHT_ARM_JOINTS,
    "left_gripper": (LEFT_GRIPPER_JOINT,),
    "right_gripper": (RIGHT_GRIPPER_JOINT,),
    "head": HEAD_JOINTS,
}

# Canonical 26-joint action set: legs -> left arm -> right arm -> grippers -> wheels.
G1_ACTION_JOINT_NAMES = (
    LEG_JOINTS + LEFT_ARM_JOINTS + RIGHT_ARM_JOINTS + (LEFT_GRIPPER_JOINT, RIGHT_GRIPPER_JOINT) + BASE_WHEEL_JOINTS
)
CONTROLLED_JOINT_NAMES = LEFT_ARM_JOINTS
DEFAULT_ARM = "left"

# ---------------------------------------------------------------- gripper
GRIPPER_OPEN = 0.0
"""Master joint target when open [rad]."""
GRIPPER_CLOSED = 1.2
"""Master joint target when closed [rad]."""
GRIPPER_VELOCITY_LIMIT = 2.0
"""Gripper master speed limit [rad/s]."""
FINGER_TRAVEL_PER_RAD = 0.0375
"""Each finger slides this far inward per radian of the master joint [m/rad]."""
FINGERTIP_REACH = 0.05
"""How far the finger pads reach along the TCP's approach axis (TCP +x) [m]: each pad's centre sits 0.0179 m from
the TCP toward the palm and is 0.0679 m long each way (MJCF), so the pads span -0.086 .. +0.050 m."""

# ---------------------------------------------------------------- joint limits beyond the MJCF ranges
JOINT_VELOCITY_LIMITS: dict[str, float] = {
    LEFT_GRIPPER_JOINT: GRIPPER_VELOCITY_LIMIT,
    RIGHT_GRIPPER_JOINT: GRIPPER_VELOCITY_LIMIT,
}
"""Per-joint speed limits [rad/s | m/s] (the reference sets only the grippers' ``velocity_limit_sim``);
``robots.g1.model.apply_spec_limits`` writes them into Newton's ``joint_velocity_limit``."""
JOINT_EFFORT_LIMITS: dict[str, float] = {}
"""Per-joint effort limits [N m | N]; the reference sets none (its drive values are authoritative).
Written into Newton's ``joint_effort_limit`` (MuJoCo's actuator force range)."""

# ---------------------------------------------------------------- base / wheels
WHEEL_RADIUS = 0.1
WHEEL_OFFSET_X = 0.176493
WHEEL_OFFSET_Y = 0.176493
NAV_MAX_SPEED = 0.45
NAV_SUCCESS_RADIUS = 0.15
WHEEL_VELOCITY_CLIP = NAV_MAX_SPEED / WHEEL_RADIUS  # 4.5 [rad/s]

# ---------------------------------------------------------------- TCP
END_EFFECTOR_LINK = {"left": "left_arm_link7", "right": "right_arm_link7"}
TCP_OFFSET_POS = (-0.25573010977804644, 0.0, 0.0)
"""TCP position in the link7 frame [m]."""
TCP_OFFSET_QUAT = (0.0, 0.0, 1.0, 0.0)
"""TCP rotation in the link7 frame, xyzw (180 deg about z)."""
TOP_DOWN_TCP_QUAT = (0.7071067811865476, 0.0, -0.7071067811865475, 0.0)
"""Top-down TCP orientation, xyzw: TCP x (approach) points down, fingers close along world y."""

# ---------------------------------------------------------------- camera mounts (MJCF sites)
CAMERA_MOUNTS = {
    "front_head": "front_head_camera",
    "left_wrist": "left_wrist_camera",
    "right_wrist": "right_wrist_camera",
}
CAMERA_FOCAL_LENGTH_MM = 24.0
CAMERA_HORIZONTAL_APERTURE_MM = 20.955
CAMERA_CLIPPING = (0.05, 15.0)


def camera_fov_x(width_px: int = 640) -> float:
    """Horizontal field of view [rad] of the reference pinhole (independent of resolution)."""
    del width_px
    return 2.0 * math.atan(CAMERA_HORIZONTAL_APERTURE_MM / (2.0 * CAMERA_FOCAL_LENGTH_MM))


# ---------------------------------------------------------------- postures
MANIPULATION_JOINT_POSITIONS = {name: 0.0 for name in G1_ACTION_JOINT_NAMES + HEAD_JOINTS}
"""Default: every action joint and the head at 0 (legs folded, arms forward, grippers open)."""

FOLDED_ARM = {"joint2": -1.0, "joint4": -1.5}
"""Reference folded-arm spec constant (per side, others 0); used by tests only."""

# Re-derived: right arm folded beside the torso (TCP near (-0.77, -0.33, 0.40) with the root at
# (-1, 0, 0)), clear of the table and of the left arm's workspace.
STOWED_RIGHT_ARM = (-1.6, -0.2, -0.9, 2.5, -0.6, 0.4, 0.35)


def leg_lift(step: float) -> tuple[float, float, float, float, float]:
    """Torso lift posture for body-height step ``step`` [rad]: (s, 3s, 2s, 0, 0)."""
    return (step, 3.0 * step, 2.0 * step, 0.0, 0.0)


TELEOP_LEG_CLAMPS = {"leg_joint1": (-0.02, 1.01), "leg_joint2": (-0.02, 2.65), "leg_joint3": (-0.02, 2.39)}
