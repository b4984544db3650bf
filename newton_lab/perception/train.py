"""YOLO-seg training (Ultralytics) on a ``yolo-export`` folder, scored on a held-out export: ``train_yolo``.

Ultralytics and torch are imported when a training runs (Ultralytics is optional: it needs torchvision).
"""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import yaml

from ..datasets.yolo import default_imgsz, read_export, training_specs
from . import SEG_MODEL, ULTRALYTICS


def need_ultralytics() -> None:
    """A one-line ``ValueError`` saying how to install Ultralytics where it is missing (checked without importing
    it)."""
    if importlib.util.find_spec("ultralytics") is None:
        raise ValueError(
            f"ultralytics is not installed here; pip install {ULTRALYTICS} (it needs torchvision; "
            f"docs/data.md#yolo-seg lists the commands)"
        )


def results_csv(trainer) -> dict[str, list[float]]:
    """``BaseTrainer.read_results_csv`` without polars (Ultralytics copies results.csv into each checkpoint)."""
    try:
        with open(trainer.csv, newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError:
        return {}
    return {k: [float(r[k]) for r in rows] for k in (rows[0] if rows else {})}


def seg_metrics(metrics, names: dict) -> dict[str, Any]:
    """Mask and box mAP of an Ultralytics ``SegmentMetrics``, overall and per class."""
    per_class = {names[int(c)]: round(float(metrics.seg.ap50[k]), 4) for k, c in enumerate(metrics.ap_class_index)}
    return {
        "mask_map50": round(float(metrics.seg.map50), 4),
        "mask_map50_95": round(float(metrics.seg.map), 4),
        "box_map50": round(float(metrics.box.map50), 4),
        "box_map50_95": round(float(metrics.box.map), 4),
        "mask_ap50_per_class": per_class,
    }


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "unknown"


def train_yolo(
    dataset: str,
    output_dir: str,
    *,
    heldout: str | None = None,
    model: str = SEG_MODEL,
    epochs: int = 60,
    time_budget_s: float | None = None,
    batch_size: int = 32,
    imgsz: int | None = None,
    device: str = "cuda:0",
    workers: int = 8,
    seed: int = 0,
    amp: bool = False,
) -> dict[str, Any]:
    """Train ``model`` (a ``*-seg.yaml`` config or a ``*.pt`` checkpoint) on the train split of export ``dataset``
    (its val split checks each epoch) for at most ``epochs`` or ``time_budget_s`` [s], then score the best weights
    on every image of export ``heldout`` (default: the dataset's val split). ``imgsz`` [px] defaults to the export's
    longer side rounded up to 32. Writes data.yaml, heldout.yaml, weights/best.pt and metrics.json into
    ``output_dir``; returns the metrics."""
    need_ultralytics()
    found = {"dataset": read_export(dataset, "dataset")}
    if heldout is not None:
        found["heldout"] = read_export(heldout, "heldout")
    import torch  # deferred: torch and Ultralytics are slow to import
    from ultralytics import YOLO  # deferred: an optional package (it needs torchvision)
    from ultralytics.engine.trainer import BaseTrainer  # deferred: as above

    out = Path(output_dir).expanduser()
    out.mkdir(parents=True, exist_ok=True)
    train_spec, eval_spec = training_specs(found["dataset"], found.get("heldout"), out)
    (out / "data.yaml").write_text(yaml.safe_dump(train_spec, sort_keys=False))
    (out / "heldout.yaml").write_text(yaml.safe_dump(eval_spec, sort_keys=False))
    imgsz = imgsz or default_imgsz(found["dataset"]["size"])
    if importlib.util.find_spec("polars") is None:
        BaseTrainer.read_results_csv = results_csv  # Ultralytics' own reader needs polars
    t0 = time.perf_counter()
    yolo = YOLO(str(Path(model).expanduser()), task="segment")
    extra = {"time": time_budget_s / 3600.0} if time_budget_s else {}
    yolo.train(
        data=str(out / "data.yaml"),
        epochs=epochs,
        imgsz=imgsz,
        batch=batch_size,
        device=device,
        workers=workers,
        seed=seed,
        amp=amp,
        plots=False,
        cache="ram",
        project=str(out.resolve()),
        name="run",
        exist_ok=True,
        verbose=False,
        **extra,
    )
    train_s = time.perf_counter() - t0
    weights, metrics = _score_best(out, imgsz, batch_size, device)
    held = found.get("heldout", found["dataset"])
    summary = {
        "heldout": str(held["root"]) if heldout else f"{held['root']} (val split)",
        "heldout_images": sum(held["images"].values()) if heldout else held["images"]["val"],
        **seg_metrics(metrics, found["dataset"]["names"]),
        "train_images": found["dataset"]["images"]["train"],
        "epochs": int(yolo.trainer.epoch) + 1 if getattr(yolo, "trainer", None) else None,
        "train_s": round(train_s, 1),
        "imgsz": imgsz,
        "model": model,
        "device": torch.cuda.get_device_name(device) if device.startswith("cuda") else "cpu",
        "weights": str(weights / "best.pt"),
        "ultralytics": _version("ultralytics"),
    }
    (out / "metrics.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def _score_best(out: Path, imgsz: int, batch_size: int, device: str):
    """The run's best weights moved to ``<out>/weights/best.pt`` and scored on the held-out split (heldout.yaml)."""
    from ultralytics import YOLO  # deferred: an optional package (it needs torchvision)

    weights = out / "weights"
    weights.mkdir(exist_ok=True)
    os.replace(out / "run" / "weights" / "best.pt", weights / "best.pt")
    metrics = YOLO(str(weights / "best.pt")).val(
        data=str(out / "heldout.yaml"),
        split="val",
        imgsz=imgsz,
        batch=batch_size,
        device=device,
        plots=False,
        project=str(out.resolve()),
        name="heldout",
        exist_ok=True,
    )
    return weights, metrics
