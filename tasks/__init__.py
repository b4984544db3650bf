"""Task packages (imported as ``newton_lab.tasks``); importing this registers every task id.

Each subpackage but ``common`` is one task family that registers its ids when imported. They are found
on disk, so adding a task touches only its own package. This is the one import by name in the project:
a loader of this package's own children (it adds no edge between layers).
"""

import importlib
import pkgutil

SHARED = ("common",)
"""Subpackages that hold shared pieces, not tasks."""

TASK_PACKAGES = tuple(sorted(m.name for m in pkgutil.iter_modules(__path__) if m.ispkg and m.name not in SHARED))

for _name in TASK_PACKAGES:
    importlib.import_module(f"{__name__}.{_name}")
