"""Task packages (imported as ``newton_lab.tasks``); importing this registers every task id."""

from . import pick_cube, reach, stack_cube  # noqa: F401  (explicit registration imports)
