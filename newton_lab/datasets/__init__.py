"""Episode datasets: robomimic-layout HDF5 / zarr v3 storage."""

from ._common import DatasetLockedError, DatasetWriteError
from .ref import DatasetProvenance, DatasetRef
from .filter_keys import read_filter_keys, set_filter_keys
from .split import split_by_phase, split_train_val
from .states import state_tree
from .storage import (FORMAT_VERSION, SUFFIXES, EpisodeWriter, delete_demos, list_demos, open_writer,
                      read_dataset_info, read_episode, read_episodes, set_dataset_attrs)

__all__ = ["DatasetRef", "DatasetProvenance", "DatasetLockedError", "DatasetWriteError", "set_dataset_attrs",
           "EpisodeWriter", "open_writer", "read_dataset_info", "read_episode", "read_episodes", "list_demos",
           "delete_demos",
           "read_filter_keys", "set_filter_keys", "split_by_phase", "split_train_val", "state_tree",
           "SUFFIXES", "FORMAT_VERSION"]
