"""Perception on the rendered cameras: YOLO-seg datasets of a task's objects, training and prediction.

``perception.export.export_yolo`` renders a task's front-head camera while its expert works and writes a YOLO-seg
dataset (the layout: ``newton_lab.datasets.yolo``); ``perception.train.train_yolo`` trains an Ultralytics
YOLO-seg model on one and scores it on a held-out export; ``perception.predict.predict_yolo`` runs a trained model
on fresh renders and draws its masks. Ultralytics is not a dependency of newton_lab (it needs torchvision): train
and predict import it when they run. This package module imports nothing, so that the command line reads the
constants below before Warp or torch loads.
"""

from __future__ import annotations

ULTRALYTICS = "ultralytics==8.4.190"
"""The Ultralytics release training and prediction were written and measured with."""
SEG_MODEL = "yolo11n-seg.yaml"
"""Default model: YOLO11-nano segmentation built from Ultralytics' bundled config (random init, no download)."""
YOLO_CAMERA = "front_head"
"""The camera the exports and predictions render."""
SORTING_FAMILY = "GalbotG1-SortToShelf"
"""Task ids with the four sorting objects (the classes of an export) start so."""
MASK_SOURCES = ("segmentation", "rgb-color")
"""Where an export's object masks come from: the segmentation image (exact) or each object's drawn colour in the
RGB frame."""
SPLIT = (0.7, 0.2, 0.1)
"""Default train, val and test fractions of an export."""
RESOLUTION = (298, 224)
"""Default image width and height [px] of an export and of a prediction (the training export's)."""
