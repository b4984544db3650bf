"""SortToShelf-All dense rewards: SortToShelf's staged rewards of the row's target object (``for_target_value``), the
Return component's, and the coherent ``(phase + r_phase) / 15`` (``tasks.common.rewards.phased_rewards``).

Return: driving (mean of ``1 - tanh(d)`` to the table position, d in m, and ``1 - tanh(|yaw error|)``), posing
(``1 - tanh(|q_legs,arm - pick posture|)``, rad): 1/2 each, 1 when its success condition (without the hold) holds.
"""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext
from newton_lab.tasks.common.rewards import Stage, drive_stage, phased_rewards, posture_shaping, staged_rewards
from newton_lab.tasks.common.terminations import all_of, at_posture
from newton_lab.tasks.sort_to_shelf.mdp import rewards as one
from newton_lab.tasks.sort_to_shelf.objects import OBJECTS

from newton_lab.task_api.cfg import RewardTermCfg
from newton_lab.task_api.terms import bind, term_factory

from .terminations import TABLE_BASE_TOL, TABLE_JOINT_TOL, TABLE_YAW_TOL, target_index


@term_factory()
def for_target_value(*, terms: tuple):
    """``terms[i]`` (a reward ``(ctx, w) -> float``) for the row whose current phase acts on object ``i``
    (``OBJECTS`` order; only that one is evaluated)."""
    n = len(terms)

    @wp.func
    def target_value(ctx: TaskContext, w: int) -> float:
        o = target_index(ctx, w)
        v = float(0.0)
        for i in range(wp.static(n)):
            if o == i:
                v = wp.static(terms[i])(ctx, w)
        return v

    return target_value


def _for_target(per_object: list[dict[str, RewardTermCfg]]) -> dict[str, RewardTermCfg]:
    """One staged reward whose terms are each object's same-named term, switched on the row's target."""
    first = per_object[0]
    if any(list(d) != list(first) or any(d[k].weight != first[k].weight for k in d) for d in per_object):
        raise ValueError("the objects' staged rewards must have the same stages and weights to switch between them")
    return {
        name: RewardTermCfg(
            func=for_target_value(terms=tuple(bind(d[name].func, d[name].params) for d in per_object)), weight=t.weight
        )
        for name, t in first.items()
    }


def return_rewards(table_xy: tuple[float, float], arm: tuple[float, ...], legs: tuple[float, ...]):
    """SortToShelf-Return: drive back to ``table_xy`` facing the table, then the pick posture (1/2 each)."""
    drive = drive_stage(goal_xy=table_xy, goal_yaw=0.0, radius=TABLE_BASE_TOL, yaw_tol=TABLE_YAW_TOL)
    posed = all_of(terms=(drive.done, at_posture(arm=arm, legs=legs, tol=TABLE_JOINT_TOL)))  # implies driving
    return staged_rewards(drive, Stage("posing", posed, posture_shaping(arm=arm, legs=legs)))


def all_rewards(phases: list[tuple[str, str]], returning: dict[str, RewardTermCfg]) -> dict[str, RewardTermCfg]:
    """SortToShelf-All: ``(phase + r_phase) / 15`` over ``phases`` (name, kind), ``r_phase`` the kind's reward of
    the row's target (``returning`` for the return kind); terms are named by kind (``pick/<term>``)."""
    objects = list(OBJECTS.values())
    by_kind = {
        "pick": _for_target([one.pick_rewards(o) for o in objects]),
        "nav": _for_target([one.nav_rewards(o) for o in objects]),
        "place": _for_target([one.place_rewards(o) for o in objects]),
        "return": returning,
    }
    return phased_rewards([(kind, by_kind[kind]) for _, kind in phases])  # one term per kind: inlined once
