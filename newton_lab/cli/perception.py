"""``newton-lab yolo-export`` / ``yolo-train`` / ``yolo-predict``: each calls ``newton_lab.perception`` with its
arguments (``newton_lab.commands.perception``, checked before Warp, torch or Ultralytics loads) and prints the
summary as one JSON line."""

from __future__ import annotations

import json

from ..commands import YoloExportArgs, YoloPredictArgs, YoloTrainArgs


def yolo_export(args: YoloExportArgs) -> int:
    from ..perception.export import export_yolo  # deferred: Warp/Newton are slow to import

    print(json.dumps(export_yolo(args.task, args.output_dir, **args.export_kwargs())))
    return 0


def yolo_train(args: YoloTrainArgs) -> int:
    from ..perception.train import train_yolo  # deferred: contourpy and PIL (torch and Ultralytics load inside)

    print(json.dumps(train_yolo(args.dataset, args.output_dir, **args.train_kwargs())))
    return 0


def yolo_predict(args: YoloPredictArgs) -> int:
    from ..perception.predict import predict_yolo  # deferred: Warp/Newton are slow to import

    print(json.dumps(predict_yolo(args.weights, args.task, args.output_dir, **args.predict_kwargs())))
    return 0
