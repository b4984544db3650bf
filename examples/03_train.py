"""Train a diffusion policy on a dataset (reference example 03).

    python examples/03_train.py --dataset-path data/pick_cube_demos_mimic.hdf5 --output-dir outputs/pick_cube

Flags: the ``TrainArgs`` of ``newton-lab train`` (``newton_lab.commands``) with this example's defaults, and
``--task``.
"""

from __future__ import annotations

from dataclasses import dataclass

from newton_lab.cli import parse_args
from newton_lab.commands import TrainArgs
from newton_lab.datasets import DatasetRef
from newton_lab.policies import Policy
from newton_lab.policies.diffusion import PRESETS


@dataclass(kw_only=True)
class TrainExampleArgs(TrainArgs):
    """``TrainArgs`` plus a check of the datasets' task."""

    task: str | None = None
    """checked against the datasets' task (optional)"""


DEFAULTS = {"dataset_path": ["data/pick_cube_demos_mimic.hdf5"], "output_dir": "outputs/pick_cube", "epochs": 20}


def main() -> None:
    args = parse_args(TrainExampleArgs, description=__doc__, defaults=DEFAULTS)
    for path in args.dataset_path if args.task else ():
        if (found := DatasetRef.open(path).task_id) != args.task:
            raise SystemExit(f"dataset {path} holds task {found}, not --task {args.task}")
    path = Policy.from_backend("diffusion").train(args.datasets(), args.train_cfg(PRESETS), resume=args.resume)
    print(f"checkpoint: {path}")


if __name__ == "__main__":
    main()
