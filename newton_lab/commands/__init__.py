"""The argument model: one ``@dataclass`` per command, shared by the console script (``newton_lab.cli``
generates its argparse parser from these classes: fields -> flags, field docstrings -> help), the examples
(``newton_lab.cli.parse_args`` with their own defaults) and the Prefect stages (``newton_lab.flows``).

A field ``num_envs`` is the flag ``--num-envs``; ``bool`` fields are switches; ``X | None`` fields are
optional; fields without a default are required; ``list[str]`` fields take one or more values; field
metadata may set ``flags`` (the spellings, default ``--field-name``) or ``positional``. Methods turn an
argument object into the keywords of the library call it drives (``make_env``, ``env.collect``, ``mimic``,
``Policy.train``, ``run_pipeline``, ``perception``'s YOLO calls), so no caller re-lists them. ``checks`` refuses bad
values in one line before Warp, Newton or torch is imported (``check_args``).
"""

from __future__ import annotations

from .bench import BenchArgs, BenchCollectArgs, BenchRefusalsArgs, BenchTrainArgs, ResultsArgs, SuiteArgs
from .env import CameraArgs, EnvArgs, RenderArgs, RerunArgs, RolloutArgs, TasksArgs, camera_option
from .perception import YoloExportArgs, YoloPredictArgs, YoloTrainArgs
from .pipeline import RECIPE_FIELDS, PipelineArgs
from .rl import TrainRLArgs
from .teleop import TeleopArgs
from .workflow import TRAIN_OVERRIDES, CollectArgs, EvaluateArgs, ExportArgs, MimicArgs, SplitArgs, TrainArgs, ViewArgs

__all__ = [
    "BenchArgs",
    "BenchCollectArgs",
    "BenchRefusalsArgs",
    "BenchTrainArgs",
    "ResultsArgs",
    "SuiteArgs",
    "CameraArgs",
    "EnvArgs",
    "RenderArgs",
    "RerunArgs",
    "RolloutArgs",
    "TasksArgs",
    "camera_option",
    "RECIPE_FIELDS",
    "TRAIN_OVERRIDES",
    "CollectArgs",
    "EvaluateArgs",
    "ExportArgs",
    "MimicArgs",
    "PipelineArgs",
    "SplitArgs",
    "TeleopArgs",
    "TrainArgs",
    "TrainRLArgs",
    "ViewArgs",
    "YoloExportArgs",
    "YoloPredictArgs",
    "YoloTrainArgs",
]
