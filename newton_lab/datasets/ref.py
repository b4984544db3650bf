"""``DatasetRef``: a dataset on disk plus its task, metadata and provenance (collect, mimic, export ...).

Provenance is stored in the dataset itself (``data.attrs['provenance']``, a JSON list), so a ref
re-opened from a path knows how the data was made.
"""

from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from .storage import SUFFIXES, delete_demos, read_dataset_info, set_dataset_attrs


@dataclass(frozen=True)
class DatasetProvenance:
    """One operation that produced or changed a dataset."""

    operation: str
    """``collect``, ``mimic``, ``export``, ``drop``, ``merge`` ..."""
    source_path: str | None = None
    config: dict[str, Any] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    created: str = ""
    """UTC ISO timestamp."""

    def as_dict(self) -> dict[str, Any]:
        return {
            "operation": self.operation,
            "source_path": self.source_path,
            "config": self.config,
            "metadata": self.metadata,
            "created": self.created,
        }


@dataclass(frozen=True)
class DatasetRef:
    """A dataset file (``.hdf5`` / ``.h5`` / ``.zarr``) and what is known about it."""

    path: Path
    task_id: str | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    """Result of the operation that returned this ref (e.g. ``saved_demo_ids`` of the last collect)."""
    provenance: tuple[DatasetProvenance, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "path", Path(self.path))

    def __getitem__(self, key: str) -> Any:
        """``ref[key]`` reads ``metadata[key]`` (the summary of the call that returned the ref)."""
        return self.metadata[key]

    @property
    def format(self) -> str:
        return SUFFIXES.get(self.path.suffix.lower(), "unknown")

    @classmethod
    def open(cls, path) -> DatasetRef:
        """A ref to an existing dataset, with its task id and stored provenance."""
        info = read_dataset_info(path)
        prov = tuple(DatasetProvenance(**p) for p in info.get("provenance", []))
        return cls(Path(path), task_id=info["task_id"], metadata={}, provenance=prov)

    def info(self) -> dict[str, Any]:
        """Task, env_args, demo ids, totals (see ``read_dataset_info``)."""
        return read_dataset_info(self.path)

    @property
    def num_demos(self) -> int:
        return self.info()["num_demos"]

    def record(
        self, operation: str, *, config: dict | None = None, metadata: dict | None = None, source_path=None
    ) -> DatasetRef:
        """Append a provenance entry, persist it in the dataset, and return the updated ref."""
        entry = DatasetProvenance(
            operation=operation,
            source_path=None if source_path is None else str(source_path),
            config=_jsonable(config or {}),
            metadata=_jsonable(metadata or {}),
            created=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        )
        stored = [p.as_dict() for p in DatasetRef.open(self.path).provenance] + [entry.as_dict()]
        set_dataset_attrs(self.path, {"provenance": json.dumps(stored)})
        return replace(self, provenance=tuple(DatasetProvenance(**p) for p in stored))

    def drop(self) -> DatasetRef:
        """Delete the episodes written by the call that returned this ref (``metadata['saved_demo_ids']``),
        e.g. after a teleop review says "drop"; counts stay consistent."""
        ids = list(self.metadata.get("saved_demo_ids", []))
        if not ids:
            raise ValueError(f"{self.path}: this ref lists no saved_demo_ids to drop; use the ref returned by collect")
        remaining = delete_demos(self.path, ids)
        meta = {**self.metadata, "saved_demo_ids": [], "dropped_demo_ids": ids, "num_demos": len(remaining)}
        ref = replace(self, metadata=meta)
        return ref.record("drop", metadata={"dropped_demo_ids": ids})


def _jsonable(obj: Any) -> Any:
    """Round-trip through JSON (numpy scalars and paths become plain values)."""
    return json.loads(json.dumps(obj, default=lambda o: o.item() if hasattr(o, "item") else str(o)))
