"""SortToShelf reset event: the four objects shuffled over the four table slots (this task's own)."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, set_entity_pose

from newton_lab.task_api.terms import term_factory

from ..objects import OBJECTS

_SLOT_Y = wp.constant(wp.vec4(*(o.pos[1] for o in OBJECTS.values())))
"""Table slot y of each object at its default place [m]."""
_Z = wp.constant(wp.vec4(*(o.pos[2] for o in OBJECTS.values())))
"""Centre height of each object on the table [m]."""
_X = wp.constant(float(next(iter(OBJECTS.values())).pos[0]))


@term_factory(entities=("objects",))
def permute_objects(*, objects: tuple[int, int, int, int]):
    """A random permutation of ``objects`` (in ``OBJECTS`` order) over the four table slots; each keeps its
    height, yaw 0."""
    slots = wp.vec4i(*objects)

    @wp.func
    def shuffle_objects(ctx: TaskContext, w: int, seed: int, stream: int, randomize: bool):
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
            set_entity_pose(ctx, w, slots[k], wp.vec3(_X, _SLOT_Y[order[k]], _Z[k]), wp.quat_identity())

    return shuffle_objects
