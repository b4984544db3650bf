"""G1 camera mounts and intrinsics (as on the reference platform), and the robot's segmentation link groups.

The reference gives each camera as an offset from a mount link in the ROS optical convention (looks along +z,
+y down, +x right). The authored G1 has no separate mount links: each mount frame is fixed in a body of the MJCF
(``MOUNT_FRAMES``), and the MJCF site of the camera (``spec.CAMERA_MOUNTS``) holds the offset turned into the
pinhole convention Newton's ``SensorCamera`` renders (looks along -z, +y up, +x right; a 180 deg turn about x).
``site_pose`` derives the site from the reference numbers; ``tests/test_cameras.py`` checks the MJCF against it.

Units: [m], [rad], [px]. Quaternions xyzw.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

from . import spec

REFERENCE_OFFSETS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float, float]]] = {
    "front_head": (
        (0.0860441614606322, -0.04430213071916153, 0.03775394593541334),
        (-0.16830090763876662, 0.686891777200189, 0.174601740354762, 0.6851048993897368),
    ),
    "left_wrist": (
        (-0.028503262323055674, 0.010121006758704362, 0.06923672234517289),
        (0.5181547595278811, -0.4896793386321121, 0.47473422704547164, -0.5160980567362753),
    ),
    "right_wrist": (
        (-0.027569458572299, 0.007515698932418123, 0.06927524658358669),
        (-0.5102597706172789, 0.4892647456674752, -0.479785589522129, 0.5196737084204334),
    ),
}
"""Camera offset from its mount link, ROS optical convention: (pos [m], rot xyzw), as the reference's code has it."""

_HALF = math.sqrt(0.5)
MOUNT_FRAMES: dict[str, tuple[str, tuple[float, float, float], tuple[float, float, float, float]]] = {
    # head_end_effector_mount_link: at the head pitch axis, x forward, y down, z left (head_link2 turned -90 deg
    # about x); the reference offset then sets the lens 8.6 cm ahead of the axis, pitched 28 deg down, level
    "front_head": ("head_link2", (0.0, 0.0, 0.0), (-_HALF, 0.0, 0.0, _HALF)),
    # <side>_arm_end_effector_mount_link: the flange where the gripper mounts (the palm's back face, 7 cm down
    # link7's -x), x along the gripper's approach, z up in the wrist image (link7 turned 180 deg about z, like the
    # TCP); the lens sits 6.9 cm above the gripper's axis, looking past the palm at the fingers
    "left_wrist": ("left_arm_link7", (-0.07, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0)),
    "right_wrist": ("right_arm_link7", (-0.07, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0)),
}
"""Mount link of each camera as a frame of an authored body: (body, pos [m], rot xyzw in that body)."""

ROS_TO_PINHOLE = (1.0, 0.0, 0.0, 0.0)
"""180 deg about x, xyzw: ROS optical frame (+z forward, +y down) -> pinhole frame (-z forward, +y up)."""

MIN_RESOLUTION = 8
MAX_RESOLUTION = 4096
"""Image sides accepted by the env [px]."""


def _quat_mul(a, b) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def _quat_rotate(q, v) -> np.ndarray:
    qv = np.array(q[:3], dtype=float)
    v = np.asarray(v, dtype=float)
    t = 2.0 * np.cross(qv, v)
    return v + q[3] * t + np.cross(qv, t)


def site_pose(mount: str) -> tuple[str, tuple[float, ...], tuple[float, ...]]:
    """(body, pos [m], quat xyzw) of ``mount``'s camera in the pinhole convention, in its body's frame."""
    body, frame_pos, frame_rot = MOUNT_FRAMES[mount]
    pos, rot = REFERENCE_OFFSETS[mount]
    q_ros = np.asarray(rot, dtype=float) / np.linalg.norm(rot)
    q = _quat_mul(_quat_mul(frame_rot, q_ros), ROS_TO_PINHOLE)
    q = q / np.linalg.norm(q)
    if q[3] < 0.0:
        q = -q
    p = np.asarray(frame_pos, dtype=float) + _quat_rotate(frame_rot, pos)
    return body, tuple(float(x) for x in p), tuple(float(x) for x in q)


def focal_px(width: int) -> float:
    """fx = fy [px] of the reference pinhole (24 mm lens over a 20.955 mm aperture) at ``width`` px: 1.1453 W."""
    return width * spec.CAMERA_FOCAL_LENGTH_MM / spec.CAMERA_HORIZONTAL_APERTURE_MM


def intrinsics(width: int, height: int) -> np.ndarray:
    """3x3 pinhole matrix K [px] (OpenCV image convention: u right, v down, principal point at the centre)."""
    f = focal_px(width)
    return np.array([[f, 0.0, 0.5 * width], [0.0, f, 0.5 * height], [0.0, 0.0, 1.0]])


def pinhole_rays(width: int, height: int, near: float = spec.CAMERA_CLIPPING[0]) -> np.ndarray:
    """(H, W, 1, 2, 3) camera-space rays of ``intrinsics``: one per pixel centre, origin on the near plane
    (``near`` [m], so nearer surfaces are clipped), unit direction; pinhole frame (-z forward, +y up)."""
    f = focal_px(width)
    u = (np.arange(width) + 0.5 - 0.5 * width) / f
    v = (np.arange(height) + 0.5 - 0.5 * height) / f
    d = np.empty((height, width, 3))
    d[..., 0] = u[None, :]
    d[..., 1] = -v[:, None]
    d[..., 2] = -1.0
    rays = np.empty((height, width, 1, 2, 3), dtype=np.float32)
    rays[:, :, 0, 0] = d * near
    rays[:, :, 0, 1] = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return rays


LINK_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("robot/base", ("base_footprint", "wheel")),
    ("robot/torso", ("leg_link",)),
    ("robot/head", ("head_link",)),
    ("robot/left_gripper", ("left_arm_link7", "left_gripper")),
    ("robot/left_arm", ("left_arm",)),
    ("robot/right_gripper", ("right_arm_link7", "right_gripper")),
    ("robot/right_arm", ("right_arm",)),
)
"""Segmentation groups of the robot's bodies: (name, body-name prefixes), first match wins (the palm, link7,
belongs to the gripper)."""


def link_group(body: str) -> str:
    """The segmentation group of robot body ``body`` (``LINK_GROUPS``)."""
    for name, prefixes in LINK_GROUPS:
        if body.startswith(prefixes):
            return name
    raise ValueError(f"G1 body {body!r} is in no segmentation group; add its prefix to LINK_GROUPS")


OUT_OF_VIEW_GROUPS = ("robot/base", "robot/torso", "robot/head")
"""Link groups no G1 camera mount sees while the arms work in front of the body: the chassis, wheels, legs and torso are
below and behind the head camera, the head's own shapes are behind its lens, and the wrist cameras look out along
the grippers.
Measured: a segmentation survey of the expert episodes of PickCube, StackCube-Phased, PickToShelf and
SortToShelf-All (front head and left wrist, 96x72, randomised) hit none of their shapes
(``tests/test_cameras.py`` checks it on PickCube's and PickToShelf's expert episodes)."""
ARM_GROUPS = {
    "left_arm": ("robot/left_arm", "robot/left_gripper"),
    "right_arm": ("robot/right_arm", "robot/right_gripper"),
}
"""An arm's joint group -> its link groups (its gripper with it)."""


def hidden_link_groups(driven: Collection[str]) -> tuple[str, ...]:
    """The link groups the cameras need not draw for an env whose actions drive the joint groups ``driven``:
    ``OUT_OF_VIEW_GROUPS`` and each arm no action moves (it holds its tucked posture beside the torso, out of every
    view: the same survey)."""
    idle = [g for arm, groups in ARM_GROUPS.items() if arm not in driven for g in groups]
    return (*OUT_OF_VIEW_GROUPS, *idle)
