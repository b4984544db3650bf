"""SortToShelf-All's phase layout: each object of a per-episode order is picked, carried to its cell and placed, and
the robot returns to the table before the next pick.

The order is a permutation of the four sorting objects (``OBJECTS`` order) drawn at reset into the task command
(``ctx.command[w, k]`` = index of the ``k``-th object to sort); phase ``p`` acts on the object at position
``p // PHASES_PER_OBJECT``.
"""

from __future__ import annotations

from newton_lab.tasks.sort_to_shelf.objects import OBJECTS

KINDS = ("pick", "nav", "place", "return")
"""The phase kinds of one object, in order; the last object has no ``return`` (the episode ends when it is placed)."""
PHASES_PER_OBJECT = len(KINDS)
"""Phases from one object's pick to the next object's pick."""
OBJECT_COUNT = len(OBJECTS)
"""Objects sorted per episode (the command's columns)."""
PICK, NAV, PLACE, RETURN = range(PHASES_PER_OBJECT)


def phase_layout() -> list[tuple[str, str]]:
    """``(phase name, kind)`` in execution order: ``pick_1, nav_1, place_1, return_1, ..., place_4`` (15)."""
    out = []
    for k in range(1, OBJECT_COUNT + 1):
        kinds = KINDS if k < OBJECT_COUNT else KINDS[:RETURN]
        out += [(f"{kind}_{k}", kind) for kind in kinds]
    return out
