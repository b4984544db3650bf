"""SortToShelf reset events."""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, set_entity_pose

from ..objects import OBJECTS
from ..scene import OBJECT_SLOT

_SLOT_Y = wp.constant(wp.vec4(*(o.pos[1] for o in OBJECTS.values())))
_Z = wp.constant(wp.vec4(*(o.pos[2] for o in OBJECTS.values())))
_X = wp.constant(float(next(iter(OBJECTS.values())).pos[0]))
_OBJECT_SLOT = wp.constant(wp.vec4i(*OBJECT_SLOT.values()))
"""Scene slot of each sorting object, in ``OBJECTS`` order."""


@wp.func
def permute_objects(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
    """A random permutation of the four objects over the four table slots (each keeps its height, yaw 0)."""
    if not randomize:
        return
    rng = wp.rand_init(seed, stream)
    order = wp.vec4i(0, 1, 2, 3)
    for i in range(3, 0, -1):  # Fisher-Yates
        j = int(wp.randi(rng)) % (i + 1)
        if j < 0:
            j = -j
        t = order[i]
        order[i] = order[j]
        order[j] = t
    for k in range(4):
        set_entity_pose(ctx, w, _OBJECT_SLOT[k], wp.vec3(_X, _SLOT_Y[order[k]], _Z[k]), wp.quat_identity())
