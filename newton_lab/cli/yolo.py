"""``newton-lab yolo-export``: a YOLO-seg dataset of the sorting objects, rendered through the G1's front-head camera
while the task's expert works (the layout: ``newton_lab.datasets.yolo``); ``yolo-train`` trains an Ultralytics
YOLO-seg model on one and scores it on a held-out export; ``yolo-predict`` runs it on fresh renders of the same
camera and draws the predicted masks. Ultralytics is not a dependency of this package (it needs torchvision):
the two commands refuse in one line without it."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import os
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from ..commands import EnvArgs

YOLO_TASK = "GalbotG1-SortToShelf-Pick-v0"
SPLIT = [0.7, 0.2, 0.1]
RESOLUTION = [298, 224]
MASK_SOURCES = ("segmentation", "rgb-color")
CAPTURE_EVERY = 8
"""Control steps between two captured frames of a row: the expert moves arm and objects in between."""


@dataclass(kw_only=True)
class YoloExportArgs(EnvArgs):
    """``newton-lab yolo-export``: rendered RGB frames + polygon labels of the four sorting objects."""

    task: str = YOLO_TASK
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


def check(args: YoloExportArgs) -> None:
    """One-line errors before Warp is imported (unset split / resolution get their defaults)."""
    args.split = SPLIT if args.split is None else args.split
    args.resolution = RESOLUTION if args.resolution is None else args.resolution
    from ..robots.registry import camera_facts  # deferred: numpy, only for this command

    _, min_side, max_side = camera_facts()

    if not args.task.startswith("GalbotG1-SortToShelf"):
        raise ValueError(f"--task {args.task}: YOLO labels are the four sorting objects; use a SortToShelf task, "
                         f"e.g. {YOLO_TASK}")
    if args.num_images < 1:
        raise ValueError(f"--num-images must be >= 1, got {args.num_images}")
    if len(args.split) != 3 or min(args.split) < 0 or not math.isclose(sum(args.split), 1.0, abs_tol=1e-6):
        raise ValueError(f"--split takes three fractions >= 0 summing to 1 (train val test), got {args.split}")
    res = args.resolution
    if len(res) != 2 or not all(min_side <= v <= max_side for v in res):
        raise ValueError(f"--resolution takes width and height in [{min_side}, {max_side}] px, got "
                         f"{' '.join(map(str, res))}; e.g. --resolution 298 224")
    if args.mask_source not in MASK_SOURCES:
        raise ValueError(f"--mask-source {args.mask_source!r} is unknown; use one of {', '.join(MASK_SOURCES)}")
    if args.preview < 0:
        raise ValueError(f"--preview must be >= 0, got {args.preview}")


def yolo_export(args: YoloExportArgs) -> int:
    check(args)
    import numpy as np  # deferred: only this command's body needs it
    from tqdm import tqdm  # deferred: only the long commands show progress

    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..datasets.yolo import YoloWriter, assign_splits, color_segmentation, label_lines  # deferred: contourpy
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..tasks.sort_to_shelf.objects import OBJECTS  # deferred: registering the tasks imports Warp

    names = list(OBJECTS)
    writer = YoloWriter(args.output_dir, names, assign_splits(args.num_images, args.split, args.seed), args.preview)
    try:
        env = make_env(args.task, **args.env_kwargs(),
                       cameras={"front_head": {"resolution": tuple(args.resolution), "data": ("rgb", "segmentation")}})
        seg_names = env.cameras.segmentation_names
        class_ids = {seg_names.index(n): k for k, n in enumerate(names) if n in seg_names}
        agent = expert_agent(env)
        with tqdm(total=args.num_images, desc="yolo-export", unit="image", disable=None) as bar:
            step = 0
            while writer.count < args.num_images:
                if step % CAPTURE_EVERY == 0:  # one batched render of every row
                    images = env.render()
                    rgb = images["front_head_rgb"].cpu().numpy()
                    seg = images["front_head_segmentation"].cpu().numpy()
                    if args.mask_source == "rgb-color":
                        colors = np.full_like(env.cameras.id_colors(), np.nan)  # the objects' colours only
                        colors[:, list(class_ids)] = env.cameras.id_colors()[:, list(class_ids)]
                        seg = [color_segmentation(rgb[r], colors[r]) for r in range(env.num_envs)]
                    for row in range(min(env.num_envs, args.num_images - writer.count)):
                        writer.add(rgb[row], label_lines(seg[row], class_ids))
                        bar.update()
                env.step(agent.act(env))
                step += 1
        summary = writer.close()
    except BaseException:
        writer.abort()
        raise
    print(json.dumps({"task": args.task, **summary}))
    return 0


ULTRALYTICS = "ultralytics==8.4.190"
"""The Ultralytics release these commands were written and measured with."""
SEG_MODEL = "yolo11n-seg.yaml"
"""Default model: YOLO11-nano segmentation built from Ultralytics' bundled config (random init, no download)."""


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


@dataclass(kw_only=True)
class YoloPredictArgs(EnvArgs):
    """``newton-lab yolo-predict``: fresh renders of the export's camera, a trained model's masks drawn on them."""

    weights: str
    """trained model (weights/best.pt of `newton-lab yolo-train`)"""
    task: str = YOLO_TASK
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


def _new_dir(flag: str, path: str) -> None:
    root = Path(path).expanduser()
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise FileExistsError(f"{flag} {root} exists and is not empty; choose a new folder")


def _need_ultralytics() -> None:
    if importlib.util.find_spec("ultralytics") is None:
        raise ValueError(f"ultralytics is not installed here; pip install {ULTRALYTICS} (it needs torchvision; "
                         f"docs/data.md#yolo-seg lists the commands)")


def check_train(args: YoloTrainArgs) -> dict:
    """One-line errors before torch or Ultralytics is imported; returns the exports read (``read_export``)."""
    from ..datasets.yolo import read_export  # deferred: numpy, PIL, contourpy

    model = Path(args.model).expanduser()
    if model.suffix == ".pt":
        if not model.is_file():
            raise FileNotFoundError(f"--model {args.model}: no such checkpoint file")
    elif not (model.suffix == ".yaml" and "-seg" in model.stem):
        raise ValueError(f"--model {args.model!r}: use a segmentation config (*-seg.yaml, e.g. {SEG_MODEL}) or a "
                         f"*.pt checkpoint")
    if args.imgsz is not None and not (32 <= args.imgsz <= 2048 and args.imgsz % 32 == 0):
        raise ValueError(f"--imgsz must be a multiple of 32 in [32, 2048], got {args.imgsz}")
    if args.time_budget_s is not None and not args.time_budget_s > 0:
        raise ValueError(f"--time-budget-s must be > 0 [s], got {args.time_budget_s}")
    _new_dir("--output-dir", args.output_dir)
    found = {"dataset": read_export(args.dataset, "--dataset")}
    if not found["dataset"]["images"]["train"]:
        raise ValueError(f"--dataset {args.dataset}: no training images (images/train is empty); export with a "
                         f"train fraction, e.g. --split 0.8 0.2 0")
    if args.heldout is not None:
        found["heldout"] = read_export(args.heldout, "--heldout")
        if found["heldout"]["names"] != found["dataset"]["names"]:
            raise ValueError(f"--heldout {args.heldout}: its classes {found['heldout']['names']} are not the "
                             f"dataset's {found['dataset']['names']}")
    _need_ultralytics()
    return found


def check_predict(args: YoloPredictArgs) -> None:
    """One-line errors before Warp, torch or Ultralytics is imported."""
    args.resolution = RESOLUTION if args.resolution is None else args.resolution
    from ..robots.registry import camera_facts  # deferred: numpy, only for this command

    _, min_side, max_side = camera_facts()
    if not args.task.startswith("GalbotG1-SortToShelf"):
        raise ValueError(f"--task {args.task}: the model knows the four sorting objects; use a SortToShelf task, "
                         f"e.g. {YOLO_TASK}")
    if not Path(args.weights).expanduser().is_file():
        raise FileNotFoundError(f"--weights {args.weights}: no such file; train one with `newton-lab yolo-train`")
    for flag, value in (("--num-images", args.num_images), ("--capture-every", args.capture_every)):
        if value < 1:
            raise ValueError(f"{flag} must be >= 1, got {value}")
    res = args.resolution
    if len(res) != 2 or not all(min_side <= v <= max_side for v in res):
        raise ValueError(f"--resolution takes width and height in [{min_side}, {max_side}] px, got "
                         f"{' '.join(map(str, res))}; e.g. --resolution 298 224")
    if not 0 <= args.conf < 1:
        raise ValueError(f"--conf must be in [0, 1), got {args.conf}")
    _new_dir("--output-dir", args.output_dir)
    _need_ultralytics()


def _results_csv(trainer) -> dict:
    """``BaseTrainer.read_results_csv`` without polars (Ultralytics copies results.csv into each checkpoint)."""
    try:
        with open(trainer.csv, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError:
        return {}
    return {k: [float(r[k]) for r in rows] for k in (rows[0] if rows else {})}


def _seg_metrics(metrics, names: dict) -> dict:
    """Mask and box mAP of an Ultralytics ``SegmentMetrics``, overall and per class."""
    per_class = {names[int(c)]: round(float(metrics.seg.ap50[k]), 4) for k, c in enumerate(metrics.ap_class_index)}
    return {"mask_map50": round(float(metrics.seg.map50), 4), "mask_map50_95": round(float(metrics.seg.map), 4),
            "box_map50": round(float(metrics.box.map50), 4), "box_map50_95": round(float(metrics.box.map), 4),
            "mask_ap50_per_class": per_class}


def yolo_train(args: YoloTrainArgs) -> int:
    found = check_train(args)
    import yaml  # deferred: only this command's body needs it

    from ..datasets.yolo import default_imgsz, training_specs  # deferred: contourpy, PIL

    out = Path(args.output_dir).expanduser()
    out.mkdir(parents=True, exist_ok=True)
    train_spec, eval_spec = training_specs(found["dataset"], found.get("heldout"), out)
    (out / "data.yaml").write_text(yaml.safe_dump(train_spec, sort_keys=False))
    (out / "heldout.yaml").write_text(yaml.safe_dump(eval_spec, sort_keys=False))
    imgsz = args.imgsz or default_imgsz(found["dataset"]["size"])

    import torch  # deferred: torch and Ultralytics are slow to import
    from ultralytics import YOLO  # deferred: an optional package (it needs torchvision)
    from ultralytics.engine.trainer import BaseTrainer  # deferred: as above

    if importlib.util.find_spec("polars") is None:
        BaseTrainer.read_results_csv = _results_csv
    t0 = time.perf_counter()
    model = YOLO(str(Path(args.model).expanduser()), task="segment")
    extra = {"time": args.time_budget_s / 3600.0} if args.time_budget_s else {}
    model.train(data=str(out / "data.yaml"), epochs=args.epochs, imgsz=imgsz, batch=args.batch_size,
                device=args.device, workers=args.workers, seed=args.seed, amp=args.amp, plots=False, cache="ram",
                project=str(out.resolve()), name="run", exist_ok=True, verbose=False, **extra)
    train_s = time.perf_counter() - t0
    best = out / "run" / "weights" / "best.pt"
    weights = out / "weights"
    weights.mkdir(exist_ok=True)
    os.replace(best, weights / "best.pt")
    metrics = YOLO(str(weights / "best.pt")).val(data=str(out / "heldout.yaml"), split="val", imgsz=imgsz,
                                                 batch=args.batch_size, device=args.device, plots=False,
                                                 project=str(out.resolve()), name="heldout", exist_ok=True)
    names = found["dataset"]["names"]
    device = torch.cuda.get_device_name(args.device) if args.device.startswith("cuda") else "cpu"
    held = found.get("heldout", found["dataset"])
    summary = {"heldout": str(held["root"]) if args.heldout else f"{held['root']} (val split)",
               "heldout_images": sum(held["images"].values()) if args.heldout else held["images"]["val"],
               **_seg_metrics(metrics, names), "train_images": found["dataset"]["images"]["train"],
               "epochs": int(model.trainer.epoch) + 1 if getattr(model, "trainer", None) else None,
               "train_s": round(train_s, 1), "imgsz": imgsz, "model": args.model, "device": device,
               "weights": str(weights / "best.pt"), "ultralytics": _version("ultralytics")}
    (out / "metrics.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(json.dumps(summary))
    return 0


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "unknown"


def yolo_predict(args: YoloPredictArgs) -> int:
    check_predict(args)
    import numpy as np  # deferred: only this command's body needs it
    from ultralytics import YOLO  # deferred: torch and Ultralytics are slow to import

    from ..agents import expert_agent  # deferred: Warp/Newton are slow to import
    from ..datasets.yolo import MIN_AREA_PX, mask_iou, montage, overlay  # deferred: contourpy, PIL
    from ..envs import make_env  # deferred: Warp/Newton are slow to import
    from ..tasks.sort_to_shelf.objects import OBJECTS  # deferred: registering the tasks imports Warp

    model = YOLO(str(Path(args.weights).expanduser()))
    names = list(OBJECTS)
    out = Path(args.output_dir).expanduser()
    (out / "frames").mkdir(parents=True, exist_ok=True)
    env = make_env(args.task, **args.env_kwargs(),
                   cameras={"front_head": {"resolution": tuple(args.resolution), "data": ("rgb", "segmentation")}})
    device = str(env.device)  # the model runs where the env renders
    seg_names = env.cameras.segmentation_names
    seg_ids = {k: seg_names.index(n) for k, n in enumerate(names) if n in seg_names}
    agent = expert_agent(env)
    pictures, frames, step = [], [], 0
    while len(frames) < args.num_images:
        if step % args.capture_every == 0:
            images = env.render()
            rgb = images["front_head_rgb"].cpu().numpy()
            seg = images["front_head_segmentation"].cpu().numpy()
            rows = range(min(env.num_envs, args.num_images - len(frames)))
            results = model.predict([rgb[r][..., ::-1].copy() for r in rows], conf=args.conf, device=device,
                                    retina_masks=True, verbose=False)  # Ultralytics takes arrays as BGR
            for r, res in zip(rows, results):
                h, w = rgb[r].shape[:2]
                if res.masks is not None:
                    masks = res.masks.data.cpu().numpy() > 0.5
                    classes = res.boxes.cls.cpu().numpy().astype(int)
                    scores = res.boxes.conf.cpu().numpy()
                else:
                    masks, classes, scores = np.zeros((0, h, w), bool), np.zeros(0, int), np.zeros(0)
                truth = {}
                for cls, sid in seg_ids.items():
                    gt = seg[r] == sid
                    if gt.sum() >= MIN_AREA_PX:
                        mine = [k for k in range(len(classes)) if classes[k] == cls]
                        truth[names[cls]] = round(mask_iou(masks[mine[0]], gt), 4) if mine else 0.0
                stem = f"{len(frames):04d}"
                picture = overlay(rgb[r], masks, classes, scores, names)
                picture.save(out / "frames" / f"{stem}.png")
                pictures.append(picture)
                frames.append({"frame": stem, "step": step, "row": r,
                               "detections": [{"class": names[c], "score": round(float(s), 4)}
                                              for c, s in zip(classes, scores)],
                               "mask_iou_vs_render": truth})
        env.step(agent.act(env))
        step += 1
    montage(pictures).save(out / "overlays.png")
    ious = [v for f in frames for v in f["mask_iou_vs_render"].values()]
    summary = {"frames": len(frames), "overlays": str(out / "overlays.png"),
               "mean_mask_iou_vs_render": round(float(np.mean(ious)), 4) if ious else None,
               "visible_objects": len(ious), "missed": sum(v == 0.0 for v in ious), "conf": args.conf}
    (out / "predictions.json").write_text(json.dumps({**summary, "per_frame": frames}, indent=1) + "\n")
    print(json.dumps(summary))
    return 0
