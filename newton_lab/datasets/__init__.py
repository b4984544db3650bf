"""Episode datasets: robomimic-layout HDF5 / zarr v3 storage."""

from ._common import DatasetLockedError, DatasetWriteError
from .ref import DatasetProvenance, DatasetRef
from .split import split_by_phase
from .storage import (FORMAT_VERSION, SUFFIXES, EpisodeWriter, delete_demos, list_demos, open_writer,
                      read_dataset_info, read_episode, set_dataset_attrs)

__all__ = ["DatasetRef", "DatasetProvenance", "DatasetLockedError", "DatasetWriteError", "set_dataset_attrs",
           "EpisodeWriter", "open_writer", "read_dataset_info", "read_episode", "list_demos", "delete_demos",
           "split_by_phase", "SUFFIXES", "FORMAT_VERSION"]
