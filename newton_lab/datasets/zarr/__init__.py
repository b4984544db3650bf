"""The zarr v3 store (``store``): its nodes and files (``nodes``), packs of many demos in few files (``packs``),
arrays derived from others (``derived``), robomimic filter-key masks (``masks``), the locked write session
(``session``), how a batch's files are written on threads (``batch_writes``) and the inode room a collection needs
(``inodes``)."""
