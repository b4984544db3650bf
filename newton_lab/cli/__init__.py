"""The ``newton-lab`` console script: ``tasks``, ``collect``, ``evaluate``, ``bench``, ``bench-train``, ...

Every command's flags are generated from its argument dataclass in ``newton_lab.commands`` (one argument
model for the CLI, the examples and the Prefect stages); ``workflow``, ``datasets``, ``env``, ``bench``, ``rl`` and
``perception`` hold what each command does (a call into the library and a printed summary).
"""

from __future__ import annotations

import argparse
import sys
from importlib import metadata

from ..commands.checks import check_args
from ..records import set_invocation
from .errors import ERRORS, error_line
from .flags import add_arguments, from_namespace
from .help_text import REQUIRED, HelpFormatter
from .parsing import add_verbose, apply_verbose, make_output_dirs, parse_args, unrecognized
from .registry import COMMANDS
from .sigterm import sigterm_as_ctrl_c


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


__all__ = ["COMMANDS", "REQUIRED", "build_parser", "main", "parse_args"]
