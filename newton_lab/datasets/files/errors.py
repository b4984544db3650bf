"""The errors a dataset write or read ends with: locked, refused by the medium, or not a dataset (one line each)."""

from __future__ import annotations

import errno
from pathlib import Path


class DatasetLockedError(BlockingIOError, ValueError):
    """Another process kept the dataset locked past the bounded wait (one line; also a ``ValueError``)."""


class DatasetWriteError(OSError):
    """The disk refused a write (ENOSPC, EIO, ...): one line saying what the dataset still holds."""

    def __init__(self, message: str, err: int) -> None:
        super().__init__(message)
        self.errno = err

    def __reduce__(self):  # crosses process boundaries (a phase writer of split): both arguments
        return type(self), (self.args[0], self.errno)


STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.EROFS})
"""OS errors of the medium that end a write session as a :class:`DatasetWriteError`."""


def damaged(path: Path, reason: str) -> ValueError:
    """One-line error for a path that does not hold a readable dataset."""
    reason = " ".join(str(reason).split())[:200]
    return ValueError(
        f"{path} is not a newton_lab dataset or is damaged ({reason}); it was left untouched: "
        "re-collect the episodes into a new path (or restore a backup)"
    )
