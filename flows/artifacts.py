"""Stage artifacts: a file or folder (dataset, checkpoint) plus its content hash."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any


def content_hash(path: str | Path) -> str:
    """sha256 over a file's bytes, or over every file (relative name + bytes) of a folder (zarr)."""
    p = Path(path)
    h = hashlib.sha256()
    files = [p] if p.is_file() else sorted(f for f in p.rglob("*") if f.is_file())
    if not files:
        raise FileNotFoundError(f"artifact {p} does not exist or is empty")
    for f in files:
        if p.is_dir():
            h.update(str(f.relative_to(p)).encode())
        with open(f, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def artifact(path: str | Path, kind: str, **metrics: Any) -> dict[str, Any]:
    """``{"path", "kind", "sha256", "metrics"}`` for a finished stage output."""
    return {"path": str(Path(path).resolve()), "kind": kind, "sha256": content_hash(path), "metrics": metrics}
