"""Episode datasets: robomimic-layout HDF5 / zarr v3 storage.

Rooms: ``hdf5/`` and ``zarr/`` (the two stores), ``files/`` (what both share on disk), ``writers/`` (the background
writer of ``collect``), ``lerobot/`` and ``yolo/`` (exports). At the top: the public API (``storage``, ``access``),
``ref`` (DatasetRef), ``split``, ``merge``, ``filter_keys`` and ``states``."""

from .files.errors import DatasetLockedError, DatasetWriteError
from .filter_keys import read_filter_keys, set_filter_keys
from .ref import DatasetProvenance, DatasetRef
from .split import split_by_phase, split_train_val
from .states import state_tree
from .storage import (
    FORMAT_VERSION,
    SUFFIXES,
    EpisodeWriter,
    delete_demos,
    list_demos,
    open_writer,
    read_dataset_info,
    read_episode,
    read_episodes,
    set_dataset_attrs,
)

__all__ = [
    "DatasetRef",
    "DatasetProvenance",
    "DatasetLockedError",
    "DatasetWriteError",
    "set_dataset_attrs",
    "EpisodeWriter",
    "open_writer",
    "read_dataset_info",
    "read_episode",
    "read_episodes",
    "list_demos",
    "delete_demos",
    "read_filter_keys",
    "set_filter_keys",
    "split_by_phase",
    "split_train_val",
    "state_tree",
    "SUFFIXES",
    "FORMAT_VERSION",
]
