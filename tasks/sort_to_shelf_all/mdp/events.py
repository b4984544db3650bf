"""SortToShelf-All reset event: the order the four objects are sorted in, drawn per episode."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext

from ..order import OBJECT_COUNT


@wp.func
def draw_sort_order(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
    """Write a random permutation of the objects (indices in ``OBJECTS`` order) into the task command: column ``k``
    is the ``k``-th object to sort. Without ``randomize``: ``OBJECTS`` order."""
    order = wp.vec4i(0, 1, 2, 3)
    if randomize:
        rng = wp.rand_init(seed, stream)
        for i in range(OBJECT_COUNT - 1, 0, -1):  # Fisher-Yates
            j = int(wp.randi(rng)) % (i + 1)
            if j < 0:
                j = -j
            t = order[i]
            order[i] = order[j]
            order[j] = t
    for k in range(OBJECT_COUNT):
        ctx.command[w, k] = float(order[k])
