"""Task packages (imported as ``newton_lab.tasks``); importing this registers every task id."""

from . import base_nav, pick_cube, pick_to_shelf, reach, sort_to_shelf, stack_cube  # noqa: F401  (explicit registration imports)
