"""Pictures of YOLO-seg predictions: masks overlaid on a frame with class names and scores, a contact sheet of
frames, and the overlap (IoU) of two masks."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw

OVERLAY_COLORS = ((255, 0, 255), (0, 255, 255), (255, 140, 0), (255, 255, 255), (160, 255, 0), (255, 90, 90))
"""Overlay colour of each class id (cycled): far from the objects' own red, blue, yellow and green."""


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (0 when both are empty)."""
    union = int((a | b).sum())
    return float((a & b).sum() / union) if union else 0.0


def overlay(
    rgb: np.ndarray,
    masks: np.ndarray,
    classes: Sequence[int],
    scores: Sequence[float],
    names: Sequence[str] | dict,
    scale: int = 3,
    alpha: float = 0.45,
) -> Image.Image:
    """An (H, W, 3) uint8 frame at ``scale`` x size with each predicted (H, W) mask of ``masks`` (N, H, W) tinted in
    its class colour (``OVERLAY_COLORS``), outlined, and named with its score at the mask's top-left corner."""
    h, w = rgb.shape[:2]
    out = rgb.astype(np.float32).copy()
    edges = []
    for mask, cls in zip(masks, classes):
        mask = np.asarray(mask, bool)
        color = np.array(OVERLAY_COLORS[int(cls) % len(OVERLAY_COLORS)], np.float32)
        out[mask] = (1 - alpha) * out[mask] + alpha * color
        inner = mask.copy()
        inner[1:, :] &= mask[:-1, :]
        inner[:-1, :] &= mask[1:, :]
        inner[:, 1:] &= mask[:, :-1]
        inner[:, :-1] &= mask[:, 1:]
        edges.append((mask & ~inner, color))
    for edge, color in edges:
        out[edge] = color
    image = Image.fromarray(out.round().clip(0, 255).astype(np.uint8)).resize((w * scale, h * scale), Image.NEAREST)
    draw = ImageDraw.Draw(image)
    for mask, cls, score in zip(masks, classes, scores):
        ys, xs = np.nonzero(np.asarray(mask, bool))
        if len(xs):
            at = (int(xs.min()) * scale, max(0, int(ys.min()) * scale - 11))
            color = OVERLAY_COLORS[int(cls) % len(OVERLAY_COLORS)]
            draw.text(at, f"{names[int(cls)]} {float(score):.2f}", fill=color)
    return image


def montage(images: Sequence[Image.Image], cols: int = 4) -> Image.Image:
    """Equal-sized pictures in a grid, ``cols`` per row, row by row."""
    w, h = images[0].size
    rows = -(-len(images) // cols)
    sheet = Image.new("RGB", (w * min(cols, len(images)), h * rows))
    for k, image in enumerate(images):
        sheet.paste(image, ((k % cols) * w, (k // cols) * h))
    return sheet
