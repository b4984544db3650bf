"""Parsing a command line into an argument dataclass (``newton_lab.commands``), checked and with its output folders
made: ``parse_args(CollectArgs)`` parses ``sys.argv`` into a ``CollectArgs``; an example passes its own
``defaults`` (a different default, or ``REQUIRED``), ``exclude`` (fields it does not expose; they keep their
default) and ``choices``. The flags themselves: ``cli.flags``.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Mapping
from typing import Any

from .. import commands as c
from ..commands.checks import check_args, check_writable
from ..kernels.runtime import set_verbose
from ..task_api.catalog import did_you_mean
from .flags import add_arguments, from_namespace
from .help_text import REQUIRED, HelpFormatter

__all__ = ["REQUIRED", "add_verbose", "apply_verbose", "make_output_dirs", "parse_args", "unrecognized"]


def unrecognized(parser: argparse.ArgumentParser, extra: list[str]) -> str:
    """argparse's ``unrecognized arguments`` message, with the closest flag of ``parser`` for each unknown
    one (``--epsiodes`` -> ``did you mean --episodes?``)."""
    flags = [s for a in parser._actions for s in a.option_strings]
    hints = [f"{x}{did_you_mean(x.split('=')[0], flags)}" for x in extra]
    return "unrecognized arguments: " + " ".join(hints)


OUTPUT_FIELDS = {
    c.CollectArgs: ("dataset_path", "save_end_scenario", "rerun_save"),
    c.EvaluateArgs: ("rerun_save",),
    c.MimicArgs: ("output_path",),
    c.ExportArgs: ("root",),
    c.ViewArgs: ("save",),
}
"""Fields naming an output file (or new folder), per argument class (and its subclasses): the command or
example creates their parent folder (``collect --dataset-path data/demos.hdf5`` into a missing ``data/``) before
Warp is imported, by the rule of the Python API (``newton_lab.datasets.files.output_paths``)."""


def make_output_dirs(args: object) -> None:
    """Create the parent folder of each ``OUTPUT_FIELDS`` path of ``args`` (after ``check_args``); a file where one
    of its folders should be, or a folder that takes no new file, is refused in one line (``OutputPathError``)."""
    from ..datasets.files.output_paths import output_path  # deferred: datasets imports h5py and zarr (~1 s)

    for cls, names in OUTPUT_FIELDS.items():
        for name in names if isinstance(args, cls) else ():
            if (value := getattr(args, name)) is not None:
                check_writable(output_path(value))


def add_verbose(parser: argparse.ArgumentParser) -> None:
    """The ``--verbose`` switch: show Warp's banner and per-module load lines (quiet by default)."""
    parser.add_argument(
        "--verbose",
        action="store_true",
        default=argparse.SUPPRESS,
        help="show Warp's start-up and module-load output (also: NEWTON_LAB_VERBOSE=1)",
    )


def apply_verbose(ns: argparse.Namespace) -> None:
    """Turn Warp's output on when ``--verbose`` was given."""
    if getattr(ns, "verbose", False):
        set_verbose()


def parse_args(
    cls: type,
    argv: list[str] | None = None,
    *,
    description: str | None = None,
    defaults: Mapping[str, Any] | None = None,
    exclude: Iterable[str] = (),
    choices: Mapping[str, Iterable[Any]] | None = None,
):
    """Parse ``argv`` (default ``sys.argv[1:]``) into a ``cls``, checked as the CLI checks it (``check_args``)
    and with its output folders created; bad input exits 2 with argparse's message (an unknown flag names the
    closest one). ``--verbose`` shows Warp's output."""
    parser = argparse.ArgumentParser(description=description, formatter_class=HelpFormatter)
    add_arguments(parser, cls, defaults=defaults, exclude=exclude, choices=choices)
    add_verbose(parser)
    ns, extra = parser.parse_known_args(argv)
    if extra:
        parser.error(unrecognized(parser, extra))
    apply_verbose(ns)
    args = from_namespace(cls, ns, defaults=defaults)
    try:
        check_args(args)
        make_output_dirs(args)
    except (ValueError, FileNotFoundError) as exc:
        parser.error(exc.args[0] if exc.args else str(exc))
    return args
