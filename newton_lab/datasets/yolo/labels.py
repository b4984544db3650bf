"""YOLO-seg labels from masks: each object's outer contour as a simplified polygon, and object masks recovered from
RGB frames by hue when no segmentation was rendered (``--mask-source rgb-color``)."""

from __future__ import annotations

import contourpy
import numpy as np

MIN_AREA_PX = 12
"""An object covering fewer mask pixels than this is not labelled (a sliver at the border or behind the gripper)."""
HUE_TOLERANCE_DEG = 12.0
"""``--mask-source rgb-color``: largest hue difference [deg] of a pixel from its object's drawn colour."""
MIN_SATURATION = 0.35
"""``--mask-source rgb-color``: pixels and colours less saturated than this are no object's (greys)."""
SIMPLIFY_PX = 0.75
"""Douglas-Peucker tolerance [px] of the label polygons."""


def mask_polygon(mask: np.ndarray, tolerance: float = SIMPLIFY_PX) -> np.ndarray | None:
    """Outer contour of the largest region of a boolean (H, W) mask as (K, 2) float (x, y) in pixel units (pixel
    k spans [k, k + 1)), simplified to ``tolerance`` px; None when the mask has fewer than ``MIN_AREA_PX`` px."""
    if int(mask.sum()) < MIN_AREA_PX:
        return None
    padded = np.pad(mask.astype(np.float64), 1)  # regions touching the border get closed contours
    lines = contourpy.contour_generator(z=padded, line_type=contourpy.LineType.Separate).lines(0.5)
    if not lines:
        return None
    outer = max(lines, key=lambda line: abs(_area(line)))  # holes and small islands are inside or smaller
    outer = outer - 1.0 + 0.5  # undo the padding; contour at pixel centres +- 0.5 -> pixel edges
    h, w = mask.shape
    outer = np.clip(outer, 0.0, [w, h])
    simplified = _douglas_peucker(outer[:-1] if np.allclose(outer[0], outer[-1]) else outer, tolerance)
    return simplified if len(simplified) >= 3 else None


def _area(line: np.ndarray) -> float:
    x, y = line[:, 0], line[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _douglas_peucker(points: np.ndarray, tolerance: float) -> np.ndarray:
    """Polyline simplification (no maintained library here does it without OpenCV / shapely, neither of which
    installs beside the pins: a dozen lines of the textbook algorithm, iterative)."""
    keep = np.zeros(len(points), bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(points) - 1)]
    while stack:
        lo, hi = stack.pop()
        if hi <= lo + 1:
            continue
        a, b = points[lo], points[hi]
        seg = b - a
        rel = points[lo + 1 : hi] - a
        norm = float(np.hypot(*seg))
        dist = np.abs(seg[0] * rel[:, 1] - seg[1] * rel[:, 0]) / norm if norm > 0 else np.hypot(rel[:, 0], rel[:, 1])
        k = int(np.argmax(dist))
        if dist[k] > tolerance:
            mid = lo + 1 + k
            keep[mid] = True
            stack += [(lo, mid), (mid, hi)]
    return points[keep]


def label_lines(segmentation: np.ndarray, class_ids: dict[int, int]) -> list[tuple[int, np.ndarray]]:
    """(class id, normalised (K, 2) polygon) of every object visible in an (H, W) id image; ``class_ids`` maps
    segmentation ids to YOLO class ids."""
    h, w = segmentation.shape
    out = []
    for seg_id, cls in class_ids.items():
        poly = mask_polygon(segmentation == seg_id)
        if poly is not None:
            out.append((cls, poly / [w, h]))
    return out


def _hue_saturation(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """HSV hue [deg] and saturation of (..., 3) colours (any scale)."""
    hi, lo = rgb.max(axis=-1), rgb.min(axis=-1)
    span = np.maximum(hi - lo, 1e-9)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    hue = np.where(hi == r, (g - b) / span % 6, np.where(hi == g, (b - r) / span + 2, (r - g) / span + 4)) * 60.0
    return hue, (hi - lo) / np.maximum(hi, 1e-9)


def color_segmentation(rgb: np.ndarray, id_colors: np.ndarray, hue_tolerance: float = HUE_TOLERANCE_DEG) -> np.ndarray:
    """An (H, W) id image from an (H, W, 3) uint8 frame alone: a saturated pixel (``MIN_SATURATION``) takes the id
    whose drawn colour (``id_colors`` (ids, 3), NaN = none) is saturated and nearest in hue, within
    ``hue_tolerance`` degrees (shading darkens a flat colour but keeps its hue); other pixels are -1. Grey
    shapes (table, robot) are never objects; two objects of one hue cannot be told apart (the vision
    randomisation can draw such pairs: use the segmentation source there)."""
    hue, sat = _hue_saturation(rgb.reshape(-1, 3).astype(np.float64))
    ref_hue, ref_sat = _hue_saturation(np.nan_to_num(id_colors, nan=0.0))
    known = np.flatnonzero(~np.isnan(id_colors).any(axis=1) & (ref_sat >= MIN_SATURATION))
    if not len(known):
        return np.full(rgb.shape[:2], -1, np.int64)
    diff = np.abs(hue[:, None] - ref_hue[None, known])
    diff = np.minimum(diff, 360.0 - diff)
    best = diff.argmin(axis=1)
    ids = known[best]
    dark = rgb.reshape(-1, 3).max(axis=1) < 20
    ids[(diff[np.arange(len(best)), best] > hue_tolerance) | (sat < MIN_SATURATION) | dark] = -1
    return ids.reshape(rgb.shape[:2])
