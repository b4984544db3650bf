"""The ``newton-lab`` console script: ``tasks``, ``collect``, ``evaluate``, ``bench``, ``bench-train``, ...

Every command's flags are generated from its argument dataclass in ``newton_lab.commands`` (one argument
model for the CLI, the examples and the Prefect stages); ``workflow``, ``env``, ``bench``, ``rl`` and ``perception``
hold what each command does (a call into the library and a printed summary).
"""

from __future__ import annotations

import argparse
import errno
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata

from .. import commands as c
from ..commands.checks import check_args
from ..records import set_invocation
from . import bench, env, perception, rl, workflow
from .flags import REQUIRED, HelpFormatter, add_arguments, from_namespace
from .parsing import add_verbose, apply_verbose, make_output_dirs, parse_args, unrecognized
from .sigterm import sigterm_as_ctrl_c


@dataclass(frozen=True)
class Command:
    """A subcommand: its argument dataclass, what it does, its one-line help."""

    args: type
    run: Callable[[object], int]
    help: str


COMMANDS: dict[str, Command] = {
    "tasks": Command(c.TasksArgs, env.list_task_ids, "list registered task ids"),
    "collect": Command(
        c.CollectArgs, workflow.collect, "collect expert episodes into HDF5 (.hdf5/.h5) or zarr (.zarr)"
    ),
    "evaluate": Command(
        c.EvaluateArgs, workflow.evaluate, "run a policy checkpoint (or the expert planner) and report the success rate"
    ),
    "mimic": Command(c.MimicArgs, workflow.mimic, "expand source demos with Mimic (successes only)"),
    "train": Command(c.TrainArgs, workflow.train, "train a diffusion policy on a dataset"),
    "train-rl": Command(
        c.TrainRLArgs,
        rl.train_rl,
        "PPO (rsl_rl) on a task's dense reward: checkpoint, curve, resume point, tensorboard log",
    ),
    "split": Command(
        c.SplitArgs, workflow.split, "robomimic train/valid filter keys (mask/), or one dataset per phase (--out)"
    ),
    "export": Command(c.ExportArgs, workflow.export, "export a dataset to LeRobot v3"),
    "pipeline": Command(c.PipelineArgs, workflow.pipeline, "Prefect flow: collect -> mimic -> train -> evaluate"),
    "view": Command(c.ViewArgs, workflow.view, "replay a recorded episode into rerun by re-applying its states"),
    "bench": Command(c.BenchArgs, bench.bench, "env-steps/s of the captured step vs the bare solver on the same model"),
    "bench-collect": Command(
        c.BenchCollectArgs,
        bench.bench_collect,
        "expert collection demos/s and per hour: physics / agent / writer seconds",
    ),
    "bench-train": Command(
        c.BenchTrainArgs, bench.bench_train, "diffusion-policy training steps/s: eager vs CUDA-graph step"
    ),
    "bench-refusals": Command(
        c.BenchRefusalsArgs,
        bench.bench_refusals,
        "each case of the bad-input table in a fresh newton-lab process: seconds to its refusal",
    ),
    "suite": Command(
        c.SuiteArgs,
        bench.suite,
        "every headline row of the results page, one product command each, records copied, page rebuilt",
    ),
    "results": Command(
        c.ResultsArgs,
        bench.results,
        "the results page's headline tables from the committed run records (--check: compare only)",
    ),
    "render": Command(c.RenderArgs, env.render, "one camera frame of a task as a PNG: RGB | depth | segmentation"),
    "teleop": Command(
        c.TeleopArgs,
        env.teleop,
        "drive a task from a teleop device (keyboard, replay, gp001, ...); keep / drop / exit each demo",
    ),
    "yolo-export": Command(
        c.YoloExportArgs,
        perception.yolo_export,
        "YOLO-seg dataset (images, polygon labels, data.yaml) of the sorting objects",
    ),
    "yolo-train": Command(
        c.YoloTrainArgs,
        perception.yolo_train,
        "train YOLO-seg (Ultralytics) on a yolo-export folder; mask mAP on a held-out export",
    ),
    "yolo-predict": Command(
        c.YoloPredictArgs,
        perception.yolo_predict,
        "a trained YOLO-seg model on fresh renders of the camera: overlay PNGs",
    ),
}
"""Subcommands in ``--help`` order."""

ERRORS = (ValueError, FileNotFoundError, FileExistsError, KeyError, ConnectionError, MemoryError)
"""Exceptions reported as one ``newton-lab <command>: error: ...`` line and exit status 2."""


def version() -> str:
    """The installed newton_lab version (``unknown`` when run from a source tree that is not installed)."""
    try:
        return metadata.version("newton_lab")
    except metadata.PackageNotFoundError:
        return "unknown"


def build_parser() -> argparse.ArgumentParser:
    """The ``newton-lab`` parser: one subparser per ``COMMANDS`` entry, flags from its dataclass, defaults
    shown in ``--help``."""
    parser = argparse.ArgumentParser(prog="newton-lab", description=__doc__, formatter_class=HelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    add_verbose(parser)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, cmd in COMMANDS.items():
        cmd_parser = sub.add_parser(name, help=cmd.help, description=cmd.help, formatter_class=HelpFormatter)
        add_arguments(cmd_parser, cmd.args)
        add_verbose(cmd_parser)
        cmd_parser.set_defaults(command_parser=cmd_parser)
    return parser


def _write_error() -> type[Exception]:
    from ..datasets import DatasetWriteError  # deferred: the datasets package imports h5py and zarr (~1 s)

    return DatasetWriteError


def main(argv: list[str] | None = None) -> int:
    set_invocation(sys.argv[1:] if argv is None else argv)  # the run records name this command line
    parser = build_parser()
    ns, extra = parser.parse_known_args(argv)
    if extra:  # an unknown flag: one line, with the closest flag of that command
        print(
            f"newton-lab {ns.command}: error: {unrecognized(ns.command_parser, extra)}; see `newton-lab "
            f"{ns.command} --help`",
            file=sys.stderr,
        )
        return 2
    apply_verbose(ns)
    cmd = COMMANDS[ns.command]
    try:
        args = from_namespace(cmd.args, ns)
        check_args(args)  # before Warp, Newton or torch is imported and before any file is created
        make_output_dirs(args)
        with sigterm_as_ctrl_c():  # SIGTERM ends a command as Ctrl-C does: what it finished kept, one line, 143
            return cmd.run(args)
    except ERRORS as exc:
        print(f"newton-lab {ns.command}: error: {error_line(exc)}", file=sys.stderr)
        return 2
    except _write_error() as exc:  # the disk refused a write: the run stops, the dataset keeps what it had
        print(f"newton-lab {ns.command}: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # the system refused something midway (permissions, a read-only file system, ...)
        print(f"newton-lab {ns.command}: error: {error_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # Ctrl-C / SIGTERM: an end, not a crash (datasets.writers.interrupts.Interrupted
        # says what was kept, and where); 130 / 143 as a shell reports a process ended by the signal
        print(f"newton-lab {ns.command}: {exc.args[0] if exc.args else 'interrupted'}", file=sys.stderr)
        return getattr(exc, "exit_status", 130)


def error_line(exc: Exception) -> str:
    """The one-line message of ``exc``: an OSError raised by the system (``[Errno 2] ...``) as what failed on which
    path, and not its bare errno; else its first argument (a KeyError's without the quotes)."""
    if isinstance(exc, OSError) and exc.errno is not None and exc.strerror:
        where = f"{exc.filename}: " if exc.filename is not None else ""
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):  # the medium, not the path: a full disk, a quota
            return (
                f"the disk refused a write ({os.strerror(exc.errno)}): {where}{exc.strerror}; free space and run "
                "it again"
            )
        return f"{where}{exc.strerror} (errno {exc.errno}); check the path and its permissions"
    return str(exc.args[0]) if exc.args else str(exc)


__all__ = ["COMMANDS", "REQUIRED", "build_parser", "main", "parse_args"]
