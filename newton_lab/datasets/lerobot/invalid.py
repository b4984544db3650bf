"""The validator's failure (``Invalid``, turned into one ``ValueError`` line by ``validate_lerobot_v3``) and its
reading primitives: a JSON or parquet file read, a condition needed, a path kept inside the dataset root."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from ..files.inside_root import OutsidePathError, contained


class Invalid(Exception):
    pass


def inside(root: Path, rel: str, what: str) -> Path:
    """``root / rel`` for a path taken from info.json; a path leaving ``root`` makes the dataset invalid."""
    try:
        return contained(root, rel, what)
    except OutsidePathError as e:
        raise Invalid(str(e)) from None


def need(cond: Any, msg: str) -> None:
    if not cond:
        raise Invalid(msg)


def is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def load_json(path: Path, rel: str) -> Any:
    need(path.is_file(), f"{rel} is missing")
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise Invalid(f"{rel} is not readable JSON ({e})") from None


def read_parquet(path: Path, rel: str, columns: list[str] | None = None) -> pa.Table:
    try:
        return pq.read_table(str(path), columns=columns)
    except (OSError, pa.ArrowException) as e:
        raise Invalid(f"{rel} is not a readable parquet file with columns {columns or 'any'} ({e})") from None
