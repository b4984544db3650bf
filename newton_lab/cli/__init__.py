"""The ``newton-lab`` console script: ``tasks``, ``collect``, ``evaluate``, ``bench``, ``bench-train``, ...

Every command's flags are generated from its argument dataclass in ``newton_lab.commands`` (one argument
model for the CLI, the examples and the Prefect stages); ``run`` holds what each command does.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass

from .. import commands as c
from ..datasets import DatasetWriteError
from . import run
from .parsing import REQUIRED, add_arguments, from_namespace, parse_args


@dataclass(frozen=True)
class Command:
    """A subcommand: its argument dataclass, what it does, its one-line help."""

    args: type
    run: Callable[[object], int]
    help: str


COMMANDS: dict[str, Command] = {
    "tasks": Command(c.TasksArgs, run.list_task_ids, "list registered task ids"),
    "collect": Command(c.CollectArgs, run.collect, "collect expert episodes into HDF5 (.hdf5/.h5) or zarr (.zarr)"),
    "evaluate": Command(c.EvaluateArgs, run.evaluate,
                        "run a policy checkpoint (or the expert planner) and report the success rate"),
    "mimic": Command(c.MimicArgs, run.mimic, "expand source demos with Mimic (successes only)"),
    "train": Command(c.TrainArgs, run.train, "train a diffusion policy on a dataset"),
    "split": Command(c.SplitArgs, run.split,
                     "robomimic train/valid filter keys (mask/), or one dataset per phase (--out)"),
    "export": Command(c.ExportArgs, run.export, "export a dataset to LeRobot v3"),
    "pipeline": Command(c.PipelineArgs, run.pipeline, "Prefect flow: collect -> mimic -> train -> evaluate"),
    "view": Command(c.ViewArgs, run.view, "replay a recorded episode into rerun by re-applying its states"),
    "bench": Command(c.BenchArgs, run.bench, "env-steps/s of the captured step vs the bare solver on the same model"),
    "bench-train": Command(c.BenchTrainArgs, run.bench_train,
                           "diffusion-policy training steps/s: eager vs CUDA-graph step"),
}
"""Subcommands in ``--help`` order."""

ERRORS = (ValueError, FileNotFoundError, FileExistsError, KeyError, ConnectionError)
"""Exceptions reported as one ``newton-lab <command>: error: ...`` line and exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    """The ``newton-lab`` parser: one subparser per ``COMMANDS`` entry, flags from its dataclass."""
    parser = argparse.ArgumentParser(prog="newton-lab", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, cmd in COMMANDS.items():
        add_arguments(sub.add_parser(name, help=cmd.help, description=cmd.help), cmd.args)
    return parser


def main(argv: list[str] | None = None) -> int:
    ns = build_parser().parse_args(argv)
    cmd = COMMANDS[ns.command]
    try:
        args = from_namespace(cmd.args, ns)
        c.check_args(args)  # before Warp, Newton or torch is imported and before any file is created
        run.quiet_warp()
        return cmd.run(args)
    except DatasetWriteError as exc:  # the disk refused a write: the run stops, the dataset keeps what it had
        print(f"newton-lab {ns.command}: error: {exc}", file=sys.stderr)
        return 1
    except ERRORS as exc:
        msg = exc.args[0] if exc.args else str(exc)
        print(f"newton-lab {ns.command}: error: {msg}", file=sys.stderr)
        return 2


__all__ = ["COMMANDS", "REQUIRED", "build_parser", "main", "parse_args"]
