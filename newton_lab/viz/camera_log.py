"""An env camera in rerun: a ``Pinhole`` at ``world/<row>/cameras/<camera>`` (intrinsics and resolution static,
the world pose per logged frame) with its image streams under it: ``rgb`` (``Image``, or a JPEG ``EncodedImage``),
``depth`` (``DepthImage``, metres, 0 where nothing is hit) and ``segmentation`` (``SegmentationImage``, ids named by
an ``AnnotationContext`` on the camera entity).

The pinhole frame is the one ``newton_lab.envs.cameras`` renders in: +x right, +y up, looking along -z
(``CAMERA_XYZ`` = RUB), so the 3D frustum points where the image looks and image row 0 is its top.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import rerun as rr
import warp as wp

from ..robots.binding import RobotBinding

CAMERA_XYZ = rr.ViewCoordinates.RUB
"""Axes of the camera poses (``env.sensors.cameras.poses``): x right, y up, z backwards (the view looks along -z)."""
IMAGE_DATA = ("rgb", "depth", "segmentation")
IMAGE_PLANE_DISTANCE = 0.15
"""Depth [m] at which the 3D view draws a camera's image plane (its frustum length)."""


@dataclass(frozen=True)
class CameraStream:
    """What a recording shows of one camera: its resolution [px], image data (of ``IMAGE_DATA``), 3x3
    intrinsics K [px] and the segmentation id names."""

    name: str
    width: int
    height: int
    data: tuple[str, ...]
    intrinsics: np.ndarray
    segmentation_names: tuple[str, ...] = ()


def camera_path(row: int, camera: str) -> str:
    """Entity path of ``camera`` of ``row`` (its images are children: ``<path>/rgb`` ...)."""
    return f"world/{row}/cameras/{camera}"


def env_streams(env) -> list[CameraStream]:
    """The cameras ``env`` renders (none for a state-only env)."""
    cams = env.sensors.cameras
    names = tuple(cams.segmentation_names) if any("segmentation" in c.data for c in cams.specs.values()) else ()
    return [
        CameraStream(
            name,
            c.width,
            c.height,
            tuple(d for d in IMAGE_DATA if d in c.data),
            np.asarray(cams.intrinsics(name), dtype=float),
            names if "segmentation" in c.data else (),
        )
        for name, c in cams.specs.items()
    ]


def dataset_streams(obs: Mapping[str, np.ndarray], env_args: Mapping, robot: RobotBinding) -> list[CameraStream]:
    """The cameras of a recorded episode: every ``obs/<camera>_<data>`` image key of a mount of ``robot``, with the
    dataset's ``env_args["newton_lab"]["cameras"]`` block for intrinsics and segmentation names (the robot's
    intrinsics at the image's size when the block lacks them)."""
    block = (env_args.get("newton_lab") or {}).get("cameras") or {}
    out = []
    for cam in robot.camera_mounts:
        data = tuple(d for d in IMAGE_DATA if f"{cam}_{d}" in obs)
        if not data:
            continue
        h, w = np.asarray(obs[f"{cam}_{data[0]}"]).shape[1:3]
        meta = block.get(cam, {})
        k = np.asarray(meta.get("intrinsics", robot.camera_intrinsics(w, h)), dtype=float).reshape(3, 3)
        names = tuple(meta.get("segmentation_names", ())) if "segmentation" in data else ()
        out.append(CameraStream(cam, int(w), int(h), data, k, names))
    return out


def mount_poses(model, body_q: np.ndarray, camera: str, robot: RobotBinding) -> np.ndarray:
    """(7,) world pose (xyz, xyzw) of ``camera``'s MJCF site (``robot.camera_mounts``) in world 0, from the bodies'
    poses ``body_q`` (bodies, 7): the camera pose of a recording without ``datagen/camera_poses``."""
    site = robot.camera_mounts[camera]
    world = model.shape_world.numpy()
    for s, label in enumerate(model.shape_label):
        if label.rsplit("/", 1)[-1] == site and world[s] == 0:
            b, xf = int(model.shape_body.numpy()[s]), model.shape_transform.numpy()[s]
            t = wp.transform_multiply(
                wp.transform(*[float(x) for x in body_q[b]]), wp.transform(*[float(x) for x in xf])
            )
            return np.array([*t.p, *t.q], dtype=np.float64)
    raise ValueError(f"the {robot.name} model has no camera site {site!r} for camera {camera!r}")


def annotation_context(names) -> rr.AnnotationContext:
    """Segmentation id -> name, with a fixed colour per id (id 0, nothing hit, black)."""
    colors = np.random.default_rng(7).integers(40, 256, size=(max(len(names), 1), 3), dtype=np.uint8)
    colors[0] = 0
    return rr.AnnotationContext(
        [rr.AnnotationInfo(id=i, label=n, color=colors[i].tolist()) for i, n in enumerate(names)]
    )


def log_camera_statics(rec: rr.RecordingStream, row: int, cam: CameraStream) -> None:
    """The camera's pinhole (K, resolution, RUB axes) and segmentation names, static."""
    path = camera_path(row, cam.name)
    rec.log(
        path,
        rr.Pinhole(
            image_from_camera=cam.intrinsics,
            resolution=[cam.width, cam.height],
            camera_xyz=CAMERA_XYZ,
            image_plane_distance=IMAGE_PLANE_DISTANCE,
        ),
        static=True,
    )
    if cam.segmentation_names:
        rec.log(path, annotation_context(cam.segmentation_names), static=True)


def log_camera_frame(
    rec: rr.RecordingStream,
    row: int,
    cam: CameraStream,
    pose,
    frames: Mapping[str, np.ndarray],
    *,
    jpeg_quality: int | None = None,
) -> None:
    """One frame of ``cam``: its world pose (xyz, xyzw) and the images of ``frames`` (``rgb`` (H, W, 3) uint8,
    ``depth`` (H, W) [m], ``segmentation`` (H, W) ids) at the recording's current time."""
    path = camera_path(row, cam.name)
    pose = np.asarray(pose, dtype=np.float64)
    rec.log(path, rr.Transform3D(translation=pose[:3], quaternion=rr.Quaternion(xyzw=pose[3:7])))
    if "rgb" in frames:
        img = rr.Image(np.ascontiguousarray(frames["rgb"], dtype=np.uint8), color_model="RGB")
        rec.log(f"{path}/rgb", img.compress(jpeg_quality) if jpeg_quality else img)
    if "depth" in frames:
        d = np.asarray(frames["depth"], dtype=np.float32)
        rec.log(f"{path}/depth", rr.DepthImage(np.where(np.isfinite(d), d, 0.0).astype(np.float32), meter=1.0))
    if "segmentation" in frames:
        s = np.asarray(frames["segmentation"])
        rec.log(
            f"{path}/segmentation", rr.SegmentationImage(s.astype(np.uint16 if s.max(initial=0) < 65536 else np.uint32))
        )
