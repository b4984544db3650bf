"""SortToShelf-All observation terms: which object the row's phase acts on (the instruction a phase policy is
conditioned on), and that object's pose (privileged)."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, entity_pose, write_transform
from newton_lab.tasks.sort_to_shelf.objects import OBJECTS

from newton_lab.task_api.cfg import ObsTermCfg
from newton_lab.task_api.terms import term_factory

from ..order import OBJECT_COUNT
from .terminations import target_index


@wp.func
def target_one_hot(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """The object the row's current phase acts on, one-hot over ``OBJECTS`` (4)."""
    o = target_index(ctx, w)
    for i in range(OBJECT_COUNT):
        v = float(0.0)
        if i == o:
            v = 1.0
        out[w, col + i] = v


@term_factory(entities=("objects",))
def target_pose_obs(*, objects: tuple[int, ...]):
    """The pose (7) of the object the row's current phase acts on, world frame; ``objects`` in ``OBJECTS`` order."""
    slots = wp.types.vector(length=len(objects), dtype=int)(*objects)

    @wp.func
    def pose_of_target(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        write_transform(out, w, col, entity_pose(ctx, w, slots[target_index(ctx, w)]))

    return pose_of_target


TARGET_ONE_HOT = ObsTermCfg(func=target_one_hot, size=OBJECT_COUNT)
"""Observation term: the target one-hot (4); not privileged (it is the task's instruction, not a measured pose), so
``obs_mode="sensors"`` keeps it."""
TARGET_POSE = ObsTermCfg(func=target_pose_obs, params={"objects": tuple(OBJECTS)}, size=7, privileged=True)
"""Observation term: the target's pose (7); privileged (``obs_mode="sensors"`` drops it)."""
