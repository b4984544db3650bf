"""What both dataset formats share on disk: the stored layout (``layout``), errors (``errors``), the writer lock
(``locking``), durability (``durability``), the test seam for a failing disk (``write_faults``), and the path rules of
every output (``output_paths``) and of paths read from files (``inside_root``), and a dataset's recording set
(``recording``: what its demos record; an append of another set is refused)."""
