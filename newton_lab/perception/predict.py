"""A trained YOLO-seg model on fresh renders of a task's front-head camera while its expert works: the predicted
masks drawn over each frame, and each visible object's mask IoU against the render's own segmentation.
Ultralytics is imported when a prediction runs (an optional package: it needs torchvision)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..agents import expert_agent
from ..datasets.yolo import MIN_AREA_PX, mask_iou, montage, overlay
from ..envs import make_env
from ..tasks.sort_to_shelf.objects import OBJECTS
from . import RESOLUTION, YOLO_CAMERA
from .train import need_ultralytics


def _detections(result, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Masks (K, H, W) bool, classes (K,) and scores (K,) of one Ultralytics result (none: empty arrays)."""
    if result.masks is None:
        return np.zeros((0, *shape), bool), np.zeros(0, int), np.zeros(0)
    return (
        result.masks.data.cpu().numpy() > 0.5,
        result.boxes.cls.cpu().numpy().astype(int),
        result.boxes.conf.cpu().numpy(),
    )


def predict_yolo(
    weights: str,
    task: str,
    output_dir: str,
    *,
    num_images: int = 8,
    capture_every: int = 40,
    conf: float = 0.25,
    resolution: Sequence[int] = RESOLUTION,
    **env_kwargs: Any,
) -> dict[str, Any]:
    """Run the model at ``weights`` on ``num_images`` renders of ``task`` (a SortToShelf task; a frame of each row
    every ``capture_every`` control steps) at ``resolution`` (width, height [px], the training export's), keeping
    detections scored ``conf`` or more. Writes frames/*.png, overlays.png and predictions.json into ``output_dir``;
    returns the summary (mean mask IoU against the render's segmentation over the visible objects).
    ``env_kwargs`` go to ``make_env``."""
    need_ultralytics()
    from ultralytics import YOLO  # deferred: torch and Ultralytics are slow to import

    model = YOLO(str(Path(weights).expanduser()))
    names = list(OBJECTS)
    out = Path(output_dir).expanduser()
    (out / "frames").mkdir(parents=True, exist_ok=True)
    env = make_env(
        task, **env_kwargs, cameras={YOLO_CAMERA: {"resolution": tuple(resolution), "data": ("rgb", "segmentation")}}
    )
    device = str(env.device)  # the model runs where the env renders
    seg_names = env.sensors.cameras.segmentation_names
    seg_ids = {k: seg_names.index(n) for k, n in enumerate(names) if n in seg_names}
    agent = expert_agent(env)
    pictures, frames, step = [], [], 0
    while len(frames) < num_images:
        if step % capture_every == 0:
            images = env.render()
            rgb = images[f"{YOLO_CAMERA}_rgb"].cpu().numpy()
            seg = images[f"{YOLO_CAMERA}_segmentation"].cpu().numpy()
            rows = range(min(env.num_envs, num_images - len(frames)))
            results = model.predict(
                [rgb[r][..., ::-1].copy() for r in rows], conf=conf, device=device, retina_masks=True, verbose=False
            )  # Ultralytics takes arrays as BGR
            for r, res in zip(rows, results):
                masks, classes, scores = _detections(res, rgb[r].shape[:2])
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
                frames.append(
                    {
                        "frame": stem,
                        "step": step,
                        "row": r,
                        "detections": [
                            {"class": names[c], "score": round(float(s), 4)} for c, s in zip(classes, scores)
                        ],
                        "mask_iou_vs_render": truth,
                    }
                )
        env.step(agent.act(env))
        step += 1
    montage(pictures).save(out / "overlays.png")
    ious = [v for f in frames for v in f["mask_iou_vs_render"].values()]
    summary = {
        "frames": len(frames),
        "overlays": str(out / "overlays.png"),
        "mean_mask_iou_vs_render": round(float(np.mean(ious)), 4) if ious else None,
        "visible_objects": len(ious),
        "missed": sum(v == 0.0 for v in ious),
        "conf": conf,
    }
    (out / "predictions.json").write_text(json.dumps({**summary, "per_frame": frames}, indent=1) + "\n")
    return summary
