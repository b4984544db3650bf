"""SortToShelf-All predicates: SortToShelf's per-object predicates, switched per row on the object its current
phase acts on (``for_target``), and the return-to-table predicate."""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext
from newton_lab.tasks.common.terminations import all_of, any_of, at_posture, base_at, dropped, held, tipped
from newton_lab.tasks.sort_to_shelf.mdp import terminations as one
from newton_lab.tasks.sort_to_shelf.objects import OBJECTS

from newton_lab.task_api.terms import term_factory

from ..order import OBJECT_COUNT, PHASES_PER_OBJECT

TABLE_BASE_TOL = 0.05
"""Return success: base within this of its reset position at the table [m] ..."""
TABLE_YAW_TOL = 0.10
"""... facing the table within this [rad] ..."""
TABLE_JOINT_TOL = 0.12
"""... legs down and the arm at ready within this [rad] ..."""
TABLE_HOLD = 20
"""... for this many consecutive steps."""


@wp.func
def target_index(ctx: TaskContext, w: int) -> int:
    """Index (``OBJECTS`` order) of the object row ``w``'s current phase acts on."""
    k = wp.min(ctx.phase[w] // PHASES_PER_OBJECT, OBJECT_COUNT - 1)
    return int(ctx.command[w, k])


@wp.func
def never(ctx: TaskContext, w: int) -> bool:
    """Holds for no row (an object that needs no check)."""
    return False


@term_factory()
def for_target(*, terms: tuple, kind: int = -1):
    """``terms[i]`` for the row whose current phase acts on object ``i`` (one predicate per object, ``OBJECTS``
    order; only that one is evaluated, so a ``held`` counter counts in its own object's phases alone). With
    ``kind`` >= 0 it holds only in phases of that kind (``order.KINDS`` index)."""
    n, kind = len(terms), int(kind)
    if n != OBJECT_COUNT:
        raise ValueError(f"for_target takes one predicate per sorting object ({OBJECT_COUNT}), got {n}")

    @wp.func
    def target_holds(ctx: TaskContext, w: int) -> bool:
        ok = bool(False)
        if wp.static(kind) < 0 or ctx.phase[w] % PHASES_PER_OBJECT == wp.static(kind):
            o = target_index(ctx, w)
            for i in range(wp.static(n)):
                if o == i:
                    ok = wp.static(terms[i])(ctx, w)
        return ok

    return target_holds


def picked():
    """Pick success of the row's target: lifted, arm at ready, held ``CARRY_HOLD`` steps."""
    return for_target(terms=tuple(one.held_at_carry(o) for o in OBJECTS.values()))


def at_place_start():
    """Nav success of the row's target: at its place position and place-start posture, held 20 steps."""
    return for_target(terms=tuple(one.held_at_place_start(o) for o in OBJECTS.values()))


def placed():
    """Place success of the row's target: in its cell, gripper open, arm back at ready."""
    return for_target(terms=tuple(one.placed(o) for o in OBJECTS.values()))


def at_table(root_xy: tuple[float, float], arm: tuple[float, ...], legs: tuple[float, ...]):
    """Return success: base back at ``root_xy`` facing the table (yaw 0), legs and arm in the pick posture, held
    ``TABLE_HOLD`` steps."""
    at = all_of(
        terms=(
            base_at(goal_xy=root_xy, radius=TABLE_BASE_TOL, goal_yaw=0.0, yaw_tol=TABLE_YAW_TOL),
            at_posture(arm=arm, legs=legs, tol=TABLE_JOINT_TOL),
        )
    )
    return held(term=at, steps=TABLE_HOLD)


def any_dropped():
    """Any of the four objects on the floor [failure]."""
    return any_of(terms=tuple(dropped(entity=o.name, below_z=one.DROP_Z) for o in OBJECTS.values()))


def target_tipped(kind: int):
    """The row's target knocked over while in a phase of ``kind`` (the pick) [failure]; objects that may lie
    (``upright_min`` 0) never count."""
    terms = tuple(tipped(entity=o.name) if o.upright_min > 0 else never for o in OBJECTS.values())
    return for_target(terms=terms, kind=kind)


def grasped_target():
    """TCP at the row's target with the gripper closed on it (subtask signal)."""
    return for_target(terms=tuple(one.grasped_object(o) for o in OBJECTS.values()))


def released_target():
    """The row's target let go inside its cell (subtask signal)."""
    return for_target(terms=tuple(one.released_in_cell(o) for o in OBJECTS.values()))
