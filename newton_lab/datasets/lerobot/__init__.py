"""Export newton_lab datasets to the LeRobot v3.0 layout (pyarrow, and PyAV for the camera streams) and check such
layouts.

``export_lerobot(dataset, root)`` turns the committed demos of an HDF5 / zarr dataset into::

    root/meta/info.json                                  schema, fps, counts, path templates
    root/meta/stats.json                                 per feature min / max / mean / std / count
    root/meta/tasks.parquet                              task_index, task (pandas index "task")
    root/meta/episodes/chunk-000/file-000.parquet        one row per episode: offsets, tasks, stats/...
    root/meta/newton_lab_source.json                     provenance: source path, exported demo ids
    root/data/chunk-000/file-000.parquet                 one row per frame, one row group per episode
    root/videos/observation.images.<term>/chunk-000/file-000.mp4   camera stream, episodes one after another

Per frame: ``observation.state`` (float32, the concatenated low-dim obs terms), ``action`` (float32),
``observation.images.<term>`` for every uint8 (T, H, W, 3) obs term (a "video" feature: mp4 files written
with PyAV, AV1 / yuv420p, located per episode by ``videos/<key>/{chunk_index, file_index, from_timestamp,
to_timestamp}`` in meta/episodes; ``video=False``: lossless PNG "image" structs in the data files),
``timestamp`` (frame_index / fps), ``frame_index``,
``episode_index``, ``index`` and ``task_index``. Data files roll over past ``data_files_size_in_mb``
(uncompressed bytes, like LeRobot); an episode never spans two files.

The export is written into a hidden sibling directory (``.<root name>.partial-*``) and renamed into
place at the end, so ``root`` either holds a complete dataset or does not exist (a killed export can
leave the hidden sibling behind; delete it).

``validate_lerobot_v3(root)`` checks a v3.0 layout structurally (files, info.json, schemas, offsets,
index / frame_index / timestamp consistency, every mp4 decoded and its episode spans checked) and raises a
one-line ``ValueError`` on the first problem.
"""

from __future__ import annotations

try:
    import pyarrow  # noqa: F401  (checked here so every submodule gets the hint)
except ImportError as exc:  # pragma: no cover - pyarrow is a dependency of newton_lab
    raise ImportError(
        "newton_lab.datasets.lerobot needs pyarrow: pip install 'pyarrow>=15' "
        "(a newton_lab dependency; reinstall newton_lab)"
    ) from exc

from .tables import CODEBASE_VERSION, ROBOT_TYPE
from .validate import validate_lerobot_v3
from .writer import export_lerobot

__all__ = ["export_lerobot", "validate_lerobot_v3", "CODEBASE_VERSION", "ROBOT_TYPE"]
