"""The HDF5 store (robomimic layout, ``store``) and the rollback journal that makes its in-place appends atomic
(``journal``)."""
