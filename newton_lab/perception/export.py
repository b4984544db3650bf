"""A YOLO-seg dataset of a task's sorting objects: RGB frames of the front-head camera, rendered as one batch over
the env rows while the task's expert works, with each object's polygon labels (from the segmentation image, or
from the object's drawn colour in the RGB frame)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from tqdm import tqdm

from ..agents import expert_agent
from ..datasets.yolo import YoloWriter, assign_splits, color_segmentation, label_lines
from ..envs import make_env
from ..tasks.sort_to_shelf.objects import OBJECTS
from . import MASK_SOURCES, RESOLUTION, SPLIT, YOLO_CAMERA

CAPTURE_EVERY = 8
"""Control steps between two captured frames of a row: the expert moves arm and objects in between."""


def export_yolo(
    task: str,
    output_dir: str,
    *,
    num_images: int = 50,
    split: Sequence[float] = SPLIT,
    resolution: Sequence[int] = RESOLUTION,
    preview: int = 0,
    mask_source: str = "segmentation",
    **env_kwargs: Any,
) -> dict[str, Any]:
    """Write ``num_images`` frames of ``task`` (a SortToShelf task) with polygon labels of the four sorting objects
    into the new folder ``output_dir``, split train / val / test by the fractions ``split`` (seeded by
    ``env_kwargs["seed"]``), at ``resolution`` (width, height [px]); ``preview`` draws the first K labelled images
    into preview/. ``env_kwargs`` go to ``make_env`` (``num_envs``, ``device``, ``seed``, ``randomize``,
    ``task_options``). Returns the writer's summary with ``task``; a failed run leaves no partial folder."""
    if mask_source not in MASK_SOURCES:
        raise ValueError(f"mask source {mask_source!r} is unknown; use one of {', '.join(MASK_SOURCES)}")
    names = list(OBJECTS)
    splits = assign_splits(num_images, list(split), env_kwargs.get("seed", 0))
    writer = YoloWriter(output_dir, names, splits, preview)
    try:
        env = make_env(
            task,
            **env_kwargs,
            cameras={YOLO_CAMERA: {"resolution": tuple(resolution), "data": ("rgb", "segmentation")}},
        )
        seg_names = env.sensors.cameras.segmentation_names
        class_ids = {seg_names.index(n): k for k, n in enumerate(names) if n in seg_names}
        agent = expert_agent(env)
        with tqdm(total=num_images, desc="yolo-export", unit="image", disable=None) as bar:
            step = 0
            while writer.count < num_images:
                if step % CAPTURE_EVERY == 0:  # one batched render of every row
                    images = env.render()
                    rgb = images[f"{YOLO_CAMERA}_rgb"].cpu().numpy()
                    seg = images[f"{YOLO_CAMERA}_segmentation"].cpu().numpy()
                    if mask_source == "rgb-color":
                        colors = np.full_like(env.sensors.cameras.id_colors(), np.nan)  # the objects' colours only
                        colors[:, list(class_ids)] = env.sensors.cameras.id_colors()[:, list(class_ids)]
                        seg = [color_segmentation(rgb[r], colors[r]) for r in range(env.num_envs)]
                    for row in range(min(env.num_envs, num_images - writer.count)):
                        writer.add(rgb[row], label_lines(seg[row], class_ids))
                        bar.update()
                env.step(agent.act(env))
                step += 1
        summary = writer.close()
    except BaseException:
        writer.abort()
        raise
    return {"task": task, **summary}
