"""How ``newton-lab`` reports a refused command: which exceptions are one ``error:`` line with exit status 2, and
the line an OSError raised by the system becomes."""

from __future__ import annotations

import errno
import os

ERRORS = (ValueError, FileNotFoundError, FileExistsError, KeyError, ConnectionError, MemoryError)
"""Exceptions reported as one ``newton-lab <command>: error: ...`` line and exit status 2."""


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
