"""YOLO segmentation datasets (Ultralytics layout) from rendered frames and their segmentation masks.

    <root>/data.yaml                       path, train / val / test folders, names {class id: name}
    <root>/images/{train,val,test}/*.png   RGB frames
    <root>/labels/{train,val,test}/*.txt   one line per visible object: class id, then x1 y1 x2 y2 ... (polygon
                                           of the mask's outer contour, normalised to [0, 1] by width / height)
    <root>/preview/*.png                   optional: frames with their polygons drawn, for a person to check

Written into a hidden sibling folder renamed into place at the end: the root is complete or absent.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Sequence
from pathlib import Path

import contourpy
import numpy as np
import yaml
from PIL import Image, ImageDraw

from .outputs import output_path

SPLITS = ("train", "val", "test")
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
        rel = points[lo + 1:hi] - a
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


def assign_splits(n: int, fractions: Sequence[float], seed: int) -> list[str]:
    """Split name of each of ``n`` images: a seeded shuffle cut at the cumulative ``fractions``."""
    counts = np.floor(np.asarray(fractions, float) * n).astype(int)
    counts[int(np.argmax(fractions))] += n - int(counts.sum())  # rounding leftovers go to the largest split
    names = np.repeat(np.array(SPLITS), counts)
    return list(np.random.default_rng(seed).permutation(names))


class YoloWriter:
    """Writes images and labels of a YOLO-seg dataset into a partial folder; ``close`` renames it to ``root``."""

    def __init__(self, root: str | os.PathLike, names: Sequence[str], splits: list[str], preview: int = 0) -> None:
        self.root = Path(root).expanduser()
        if self.root.exists() and (not self.root.is_dir() or any(self.root.iterdir())):
            raise FileExistsError(f"--output-dir {self.root} exists and is not empty; choose a new folder")
        self.names, self.splits, self.preview = list(names), splits, preview
        output_path(self.root)
        self.tmp = self.root.parent / f".{self.root.name}.partial-{uuid.uuid4().hex}"
        for split in SPLITS:
            (self.tmp / "images" / split).mkdir(parents=True)
            (self.tmp / "labels" / split).mkdir(parents=True)
        if preview:
            (self.tmp / "preview").mkdir()
        self.count = 0
        self.seen = np.zeros(len(self.names), np.int64)  # labelled instances per class

    def add(self, rgb: np.ndarray, labels: list[tuple[int, np.ndarray]]) -> None:
        """One (H, W, 3) uint8 frame and its labels, into the next image's split."""
        split, stem = self.splits[self.count], f"{self.count:06d}"
        Image.fromarray(rgb).save(self.tmp / "images" / split / f"{stem}.png")
        text = "".join(f"{cls} " + " ".join(f"{v:.6f}" for v in poly.reshape(-1)) + "\n" for cls, poly in labels)
        (self.tmp / "labels" / split / f"{stem}.txt").write_text(text)
        for cls, _ in labels:
            self.seen[cls] += 1
        if self.count < self.preview:
            self._draw(rgb, labels).save(self.tmp / "preview" / f"{stem}.png")
        self.count += 1

    def _draw(self, rgb: np.ndarray, labels: list[tuple[int, np.ndarray]]) -> Image.Image:
        """The frame at 3x size with each polygon outlined and named."""
        scale = 3
        h, w = rgb.shape[:2]
        image = Image.fromarray(rgb).resize((w * scale, h * scale), Image.NEAREST)
        draw = ImageDraw.Draw(image)
        for cls, poly in labels:
            pts = [(float(x) * w * scale, float(y) * h * scale) for x, y in poly]
            draw.line(pts + [pts[0]], fill=(255, 0, 255), width=2)
            draw.text(pts[0], self.names[cls], fill=(255, 255, 0))
        return image

    def close(self) -> dict[str, object]:
        """Write data.yaml and move the dataset into place; returns a summary."""
        spec = {"path": str(self.root.resolve()), **{s: f"images/{s}" for s in SPLITS},
                "names": dict(enumerate(self.names))}
        (self.tmp / "data.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
        if self.root.exists():
            self.root.rmdir()  # an empty folder (checked at the start)
        os.rename(self.tmp, self.root)
        return {"output_dir": str(self.root), "images": self.count,
                "splits": {s: self.splits[:self.count].count(s) for s in SPLITS},
                "instances": dict(zip(self.names, self.seen.tolist()))}

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


# ---- training and inference (``newton-lab yolo-train`` / ``yolo-predict``): the parts that need no Ultralytics ----

OVERLAY_COLORS = ((255, 0, 255), (0, 255, 255), (255, 140, 0), (255, 255, 255), (160, 255, 0), (255, 90, 90))
"""Overlay colour of each class id (cycled): far from the objects' own red, blue, yellow and green."""


def read_export(root: str | os.PathLike, flag: str = "--dataset") -> dict[str, object]:
    """What a ``yolo-export`` folder holds: ``names`` (class id -> name), ``images`` (PNG count per split) and
    ``size`` (width, height of its first image); one-line ``FileNotFoundError`` / ``ValueError`` naming ``flag``."""
    root = Path(root).expanduser()
    spec_file = root / "data.yaml"
    if not spec_file.is_file():
        raise FileNotFoundError(f"{flag} {root}: no data.yaml there; write a dataset with `newton-lab yolo-export`")
    try:
        spec = yaml.safe_load(spec_file.read_text())
        names = {int(k): str(v) for k, v in dict(spec["names"]).items()}
    except (yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ValueError(f"{flag} {root}: data.yaml has no names list ({type(exc).__name__}); write a dataset with "
                         f"`newton-lab yolo-export`") from None
    images = {s: len(list((root / "images" / s).glob("*.png"))) for s in SPLITS}
    if not sum(images.values()):
        raise ValueError(f"{flag} {root}: no images under images/{{train,val,test}}")
    first = next(p for s in SPLITS for p in sorted((root / "images" / s).glob("*.png")))
    with Image.open(first) as im:
        size = im.size
    return {"root": root.resolve(), "names": names, "images": images, "size": size}


def training_specs(dataset: dict, heldout: dict | None, out: str | os.PathLike) -> tuple[dict, dict]:
    """The Ultralytics data specs of a run: training on ``dataset``'s train split with its val split for the
    per-epoch checks, and the evaluation spec: every image of ``heldout`` (all its splits), or ``dataset``'s val
    split without one. Absolute folders; labels are found by Ultralytics' rule (``images`` -> ``labels``)."""
    def dirs(ds: dict, splits) -> list[str]:
        return [str(ds["root"] / "images" / s) for s in splits if ds["images"][s]]

    names = dict(dataset["names"])
    train = {"path": str(Path(out).expanduser().resolve()), "train": dirs(dataset, ["train"]),
             "val": dirs(dataset, ["val"]) or dirs(dataset, ["train"]), "names": names}
    evaluate = dict(train, val=dirs(heldout, SPLITS) if heldout else train["val"])
    return train, evaluate


def default_imgsz(size: Sequence[int], stride: int = 32) -> int:
    """The network input side for frames of ``size`` (width, height): the longer side, rounded up to ``stride``."""
    return int(-(-max(size) // stride) * stride)


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (0 when both are empty)."""
    union = int((a | b).sum())
    return float((a & b).sum() / union) if union else 0.0


def overlay(rgb: np.ndarray, masks: np.ndarray, classes: Sequence[int], scores: Sequence[float],
            names: Sequence[str] | dict, scale: int = 3, alpha: float = 0.45) -> Image.Image:
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
