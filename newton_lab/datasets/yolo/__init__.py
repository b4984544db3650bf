"""YOLO-seg exports of rendered frames: labels from masks (``labels``), the Ultralytics folder layout and what
training reads of it (``export``), and pictures of predictions (``pictures``)."""

from .export import SPLITS, YoloWriter, assign_splits, default_imgsz, read_export, training_specs
from .labels import (
    HUE_TOLERANCE_DEG,
    MIN_AREA_PX,
    MIN_SATURATION,
    SIMPLIFY_PX,
    color_segmentation,
    label_lines,
    mask_polygon,
)
from .pictures import OVERLAY_COLORS, mask_iou, montage, overlay

__all__ = [
    "SPLITS",
    "YoloWriter",
    "assign_splits",
    "default_imgsz",
    "read_export",
    "training_specs",
    "HUE_TOLERANCE_DEG",
    "MIN_AREA_PX",
    "MIN_SATURATION",
    "SIMPLIFY_PX",
    "color_segmentation",
    "label_lines",
    "mask_polygon",
    "OVERLAY_COLORS",
    "mask_iou",
    "montage",
    "overlay",
]
