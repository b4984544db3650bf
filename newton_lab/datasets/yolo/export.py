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

import numpy as np
import yaml
from PIL import Image, ImageDraw

from ..files.output_paths import output_path

SPLITS = ("train", "val", "test")


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
        spec = {
            "path": str(self.root.resolve()),
            **{s: f"images/{s}" for s in SPLITS},
            "names": dict(enumerate(self.names)),
        }
        (self.tmp / "data.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
        if self.root.exists():
            self.root.rmdir()  # an empty folder (checked at the start)
        os.rename(self.tmp, self.root)
        return {
            "output_dir": str(self.root),
            "images": self.count,
            "splits": {s: self.splits[: self.count].count(s) for s in SPLITS},
            "instances": dict(zip(self.names, self.seen.tolist())),
        }

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


# ---- what training and prediction read of an export (``newton-lab yolo-train`` / ``yolo-predict``) ----


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
        raise ValueError(
            f"{flag} {root}: data.yaml has no names list ({type(exc).__name__}); write a dataset with "
            f"`newton-lab yolo-export`"
        ) from None
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
    train = {
        "path": str(Path(out).expanduser().resolve()),
        "train": dirs(dataset, ["train"]),
        "val": dirs(dataset, ["val"]) or dirs(dataset, ["train"]),
        "names": names,
    }
    evaluate = dict(train, val=dirs(heldout, SPLITS) if heldout else train["val"])
    return train, evaluate


def default_imgsz(size: Sequence[int], stride: int = 32) -> int:
    """The network input side for frames of ``size`` (width, height): the longer side, rounded up to ``stride``."""
    return int(-(-max(size) // stride) * stride)
