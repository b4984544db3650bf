"""``newton-lab yolo-export``: a YOLO-seg dataset of the sorting objects, rendered through the G1's front-head camera
while the task's expert works (the layout: ``newton_lab.datasets.yolo``)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

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
