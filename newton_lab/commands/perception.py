"""``newton-lab yolo-export`` / ``yolo-train`` / ``yolo-predict``: the arguments of ``newton_lab.perception``'s YOLO-seg
export, training and prediction, and their one-line checks (before Warp, torch or Ultralytics is imported)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..perception import MASK_SOURCES, RESOLUTION, SEG_MODEL, SORTING_FAMILY, SPLIT
from .env import EnvArgs

SORTING_TASK = "GalbotG1-SortToShelf-Pick-v0"
"""The default ``--task`` of yolo-export and yolo-predict: a SortToShelf task (its four objects are the classes)."""


@dataclass(kw_only=True)
class YoloExportArgs(EnvArgs):
    """``newton-lab yolo-export``: rendered RGB frames + polygon labels of the four sorting objects."""

    task: str = SORTING_TASK
    """task id with a front_head camera and the four sorting objects (the SortToShelf family)"""
    num_images: int = 50
    """Images to write (over all splits)."""
    output_dir: str = "outputs/yolo"
    """new dataset folder (must not exist, or be empty)"""
    split: list[float] | None = None
    """train, val and test fractions (sum 1; default 0.7 0.2 0.1)"""
    resolution: list[int] | None = None
    """image width and height [px] (default 298 224)"""
    preview: int = 0
    """also draw the polygons of the first K images into preview/*.png"""
    num_envs: int = 4
    """Parallel env rows (worlds) rendered as one batch."""
    mask_source: str = "segmentation"
    """object masks from the segmentation image (exact) or rgb-color (the RGB frame and each object's drawn colour)"""

    def export_kwargs(self) -> dict[str, Any]:
        """Keywords of ``perception.export.export_yolo(self.task, self.output_dir, **...)``."""
        return {
            "num_images": self.num_images,
            "split": self.split or SPLIT,
            "resolution": self.resolution or RESOLUTION,
            "preview": self.preview,
            "mask_source": self.mask_source,
            **self.env_kwargs(),
        }


@dataclass(kw_only=True)
class YoloTrainArgs:
    """``newton-lab yolo-train``: YOLO-seg (Ultralytics) on a ``yolo-export`` folder, scored on a held-out one."""

    dataset: str
    """training export (a `newton-lab yolo-export` folder): its train split trains, its val split checks each epoch"""
    heldout: str | None = None
    """held-out export (other seed, --randomize) scored at the end, all its images (default: the dataset's val split)"""
    model: str = SEG_MODEL
    """Ultralytics segmentation model: a *-seg.yaml config (random init) or a *.pt checkpoint file"""
    epochs: int = 60
    """epochs at most (--time-budget-s may stop earlier)"""
    time_budget_s: float | None = None
    """wall-clock training budget [s] (Ultralytics' time=; it rescales the epochs to fit)"""
    batch_size: int = 32
    """Images per batch."""
    imgsz: int | None = None
    """network input side [px], a multiple of 32 (default: the export's longer side rounded up)"""
    device: str = "cuda:0"
    """training device: cuda, cuda:N or cpu"""
    workers: int = 8
    """Data-loader worker processes."""
    seed: int = 0
    """Training seed."""
    amp: bool = False
    """mixed precision (Ultralytics' AMP check downloads yolo26n.pt; off by default so that no download is tried)"""
    output_dir: str = "outputs/yolo_train"
    """new run folder (must not exist, or be empty): data.yaml, heldout.yaml, weights/best.pt, metrics.json"""

    def train_kwargs(self) -> dict[str, Any]:
        """Keywords of ``perception.train.train_yolo(self.dataset, self.output_dir, **...)``."""
        return {
            "heldout": self.heldout,
            "model": self.model,
            "epochs": self.epochs,
            "time_budget_s": self.time_budget_s,
            "batch_size": self.batch_size,
            "imgsz": self.imgsz,
            "device": self.device,
            "workers": self.workers,
            "seed": self.seed,
            "amp": self.amp,
        }


@dataclass(kw_only=True)
class YoloPredictArgs(EnvArgs):
    """``newton-lab yolo-predict``: fresh renders of the export's camera, a trained model's masks drawn on them."""

    weights: str
    """trained model (weights/best.pt of `newton-lab yolo-train`)"""
    task: str = SORTING_TASK
    """task id with a front_head camera and the four sorting objects (the SortToShelf family)"""
    num_images: int = 8
    """Frames to render and predict."""
    num_envs: int = 4
    """Parallel env rows (worlds) rendered as one batch."""
    capture_every: int = 40
    """control steps between two frames of a row (the expert works in between)"""
    resolution: list[int] | None = None
    """image width and height [px]: the training export's (default 298 224)"""
    conf: float = 0.25
    """Smallest score of a drawn prediction."""
    output_dir: str = "outputs/yolo_predict"
    """new folder (must not exist, or be empty): overlays.png, frames/*.png, predictions.json"""

    def predict_kwargs(self) -> dict[str, Any]:
        """Keywords of ``perception.predict.predict_yolo(self.weights, self.task, self.output_dir, **...)``."""
        return {
            "num_images": self.num_images,
            "capture_every": self.capture_every,
            "conf": self.conf,
            "resolution": self.resolution or RESOLUTION,
            **self.env_kwargs(),
        }


def new_folder(flag: str, path: str) -> None:
    """``path`` is a new folder, or an empty one."""
    root = Path(path).expanduser()
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise FileExistsError(f"{flag} {root} exists and is not empty; choose a new folder")


def check_resolution(resolution: list[int] | None) -> None:
    """``--resolution``: width and height [px] in the cameras' range (unset: the default)."""
    from ..robots.registry import camera_facts  # deferred: numpy, only for the commands that render

    _, min_side, max_side = camera_facts()
    if resolution is not None and (len(resolution) != 2 or not all(min_side <= v <= max_side for v in resolution)):
        raise ValueError(
            f"--resolution takes width and height in [{min_side}, {max_side}] px, got "
            f"{' '.join(map(str, resolution))}; e.g. --resolution 298 224"
        )


def check_sorting_task(task: str, why: str) -> None:
    if not task.startswith(SORTING_FAMILY):
        raise ValueError(f"--task {task}: {why}; use a SortToShelf task, e.g. {SORTING_TASK}")


def check_yolo_export(args: YoloExportArgs) -> None:
    check_sorting_task(args.task, "YOLO labels are the four sorting objects")
    if args.num_images < 1:
        raise ValueError(f"--num-images must be >= 1, got {args.num_images}")
    split = args.split
    if split is not None and (len(split) != 3 or min(split) < 0 or not math.isclose(sum(split), 1.0, abs_tol=1e-6)):
        raise ValueError(f"--split takes three fractions >= 0 summing to 1 (train val test), got {split}")
    check_resolution(args.resolution)
    if args.mask_source not in MASK_SOURCES:
        raise ValueError(f"--mask-source {args.mask_source!r} is unknown; use one of {', '.join(MASK_SOURCES)}")
    if args.preview < 0:
        raise ValueError(f"--preview must be >= 0, got {args.preview}")


def check_yolo_train(args: YoloTrainArgs) -> None:
    """The model, sizes and folders of a training, and the exports it reads (their headers), before torch."""
    from ..datasets.yolo import read_export  # deferred: numpy, PIL, contourpy
    from ..perception.train import need_ultralytics  # deferred: as above

    model = Path(args.model).expanduser()
    if model.suffix == ".pt":
        if not model.is_file():
            raise FileNotFoundError(f"--model {args.model}: no such checkpoint file")
    elif not (model.suffix == ".yaml" and "-seg" in model.stem):
        raise ValueError(
            f"--model {args.model!r}: use a segmentation config (*-seg.yaml, e.g. {SEG_MODEL}) or a *.pt checkpoint"
        )
    if args.imgsz is not None and not (32 <= args.imgsz <= 2048 and args.imgsz % 32 == 0):
        raise ValueError(f"--imgsz must be a multiple of 32 in [32, 2048], got {args.imgsz}")
    new_folder("--output-dir", args.output_dir)
    dataset = read_export(args.dataset, "--dataset")
    if not dataset["images"]["train"]:
        raise ValueError(
            f"--dataset {args.dataset}: no training images (images/train is empty); export with a "
            f"train fraction, e.g. --split 0.8 0.2 0"
        )
    if args.heldout is not None:
        heldout = read_export(args.heldout, "--heldout")
        if heldout["names"] != dataset["names"]:
            raise ValueError(
                f"--heldout {args.heldout}: its classes {heldout['names']} are not the dataset's {dataset['names']}"
            )
    need_ultralytics()


def check_yolo_predict(args: YoloPredictArgs) -> None:
    """The task, weights, counts and folder of a prediction, before Warp, torch or Ultralytics."""
    from ..perception.train import need_ultralytics  # deferred: numpy, PIL, contourpy

    check_sorting_task(args.task, "the model knows the four sorting objects")
    if not Path(args.weights).expanduser().is_file():
        raise FileNotFoundError(f"--weights {args.weights}: no such file; train one with `newton-lab yolo-train`")
    for flag, value in (("--num-images", args.num_images), ("--capture-every", args.capture_every)):
        if value < 1:
            raise ValueError(f"{flag} must be >= 1, got {value}")
    check_resolution(args.resolution)
    if not 0 <= args.conf < 1:
        raise ValueError(f"--conf must be in [0, 1), got {args.conf}")
    new_folder("--output-dir", args.output_dir)
    need_ultralytics()
