"""Pose maths for Mimic: 7-vectors (x, y, z, qx, qy, qz, qw) <-> 4x4 matrices, the object-centric
segment transform, and pose interpolation (position lerp, rotation slerp). numpy, batched."""

from __future__ import annotations

import numpy as np

from ..task_api.motion_plan import yaw_of


def quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(..., 4) xyzw -> (..., 3, 3)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def mat_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 4) xyzw with w >= 0."""
    m = np.asarray(m, dtype=np.float64)
    t = np.trace(m, axis1=-2, axis2=-1)
    q = np.empty(m.shape[:-2] + (4,))
    # largest-component branch for numerical safety, every matrix at once
    r = {(i, j): m[..., i, j] for i in range(3) for j in range(3)}
    cand = np.stack([t, r[0, 0], r[1, 1], r[2, 2]], -1)
    k = np.argmax(cand, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):  # the branches not taken may be sqrt(<0) or /0
        s = (
            np.stack(
                [
                    np.sqrt(1.0 + t),
                    np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]),
                    np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]),
                    np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]),
                ],
                -1,
            )
            * 2
        )
        s0, s1, s2, s3 = (s[..., i] for i in range(4))
        branches = np.stack(
            [
                np.stack([(r[2, 1] - r[1, 2]) / s0, (r[0, 2] - r[2, 0]) / s0, (r[1, 0] - r[0, 1]) / s0, 0.25 * s0], -1),
                np.stack([0.25 * s1, (r[0, 1] + r[1, 0]) / s1, (r[0, 2] + r[2, 0]) / s1, (r[2, 1] - r[1, 2]) / s1], -1),
                np.stack([(r[0, 1] + r[1, 0]) / s2, 0.25 * s2, (r[1, 2] + r[2, 1]) / s2, (r[0, 2] - r[2, 0]) / s2], -1),
                np.stack([(r[0, 2] + r[2, 0]) / s3, (r[1, 2] + r[2, 1]) / s3, 0.25 * s3, (r[1, 0] - r[0, 1]) / s3], -1),
            ],
            -2,
        )
    q[...] = np.take_along_axis(branches, k[..., None, None], axis=-2)[..., 0, :]
    q *= np.where(q[..., 3:4] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def pose_to_mat(p: np.ndarray) -> np.ndarray:
    """(..., 7) -> (..., 4, 4)."""
    p = np.asarray(p, dtype=np.float64)
    m = np.zeros(p.shape[:-1] + (4, 4))
    m[..., :3, :3] = quat_to_mat(p[..., 3:7])
    m[..., :3, 3] = p[..., :3]
    m[..., 3, 3] = 1.0
    return m


def mat_to_pose(m: np.ndarray) -> np.ndarray:
    """(..., 4, 4) -> (..., 7)."""
    return np.concatenate([m[..., :3, 3], mat_to_quat(m[..., :3, :3])], axis=-1)


def transform_segment(src_eef: np.ndarray, src_obj: np.ndarray, cur_obj: np.ndarray) -> np.ndarray:
    """Object-centric replay: ``T_new = T_obj_cur · T_obj_src^-1 · T_src_eef`` for every pose of the
    segment. ``src_eef`` (T, 7); ``src_obj`` / ``cur_obj`` (7,) object poses at the segment start."""
    return transform_segments([src_eef], np.asarray(src_obj)[None], np.asarray(cur_obj)[None])[0]


def transform_segments(src_eef: list[np.ndarray], src_obj: np.ndarray, cur_obj: np.ndarray) -> list[np.ndarray]:
    """``transform_segment`` of many segments at once (the rows that start a subtask in one step): segment ``i``
    (T_i, 7) with object poses ``src_obj[i]`` / ``cur_obj[i]`` ((R, 7) each); one matrix product for every pose."""
    lengths = [len(seg) for seg in src_eef]
    delta = pose_to_mat(cur_obj) @ np.linalg.inv(pose_to_mat(src_obj))
    moved = mat_to_pose(np.repeat(delta, lengths, axis=0) @ pose_to_mat(np.concatenate(src_eef)))
    return np.split(moved, np.cumsum(lengths)[:-1])


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation between two xyzw quaternions at fractions ``t`` (n,) -> (n, 4)."""
    q0 = q0 / np.linalg.norm(q0)
    q1 = q1 / np.linalg.norm(q1)
    d = float(np.dot(q0, q1))
    if d < 0.0:
        q1, d = -q1, -d
    t = np.asarray(t, dtype=np.float64)[:, None]
    if d > 0.9995:
        q = (1 - t) * q0 + t * q1
    else:
        th = np.arccos(np.clip(d, -1.0, 1.0))
        q = (np.sin((1 - t) * th) * q0 + np.sin(t * th) * q1) / np.sin(th)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def interpolate_poses(a: np.ndarray, b: np.ndarray, steps: int) -> np.ndarray:
    """``steps`` poses strictly between ``a`` and ``b`` (exclusive of a, inclusive of b): (steps, 7)."""
    if steps <= 0:
        return np.zeros((0, 7))
    t = np.arange(1, steps + 1) / steps
    pos = a[:3] + t[:, None] * (b[:3] - a[:3])
    return np.concatenate([pos, slerp(a[3:7], b[3:7], t)], axis=1)


def rotation_angle(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Angle [rad] of the relative rotation between xyzw quaternions (broadcast)."""
    d = np.abs(np.sum(qa * qb, axis=-1))
    return 2.0 * np.arccos(np.clip(d, -1.0, 1.0))


def closest_symmetric_pose(cur: np.ndarray, ref: np.ndarray, period: float) -> np.ndarray:
    """``cur`` (7,) turned about its own z by the multiple of ``period`` [rad] that brings its yaw closest
    to ``ref``'s (for objects that look the same after that turn); ``ref`` (..., 7) gives (..., 7)."""
    ref = np.asarray(ref, dtype=np.float64)
    half = 0.5 * np.round((yaw_of(ref[..., 3:7]) - yaw_of(cur[3:7])) / period) * period
    turn = np.stack([np.zeros_like(half), np.zeros_like(half), np.sin(half), np.cos(half)], -1)
    out = np.broadcast_to(np.asarray(cur, dtype=np.float64), ref.shape).copy()
    out[..., 3:7] = mat_to_quat(quat_to_mat(cur[3:7]) @ quat_to_mat(turn))
    return out
