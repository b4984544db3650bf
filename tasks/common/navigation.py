"""Navigation terms shared by the mobile tasks (BaseNav, the Nav phases of PickToShelf / SortToShelf).

The goal is a task constant: the terms are generic ones (``@term_factory``) taking it as a parameter, so it
becomes a compile-time constant of the generated ``@wp.func``. Base pose = planar base coordinates
(x, y [m], yaw [rad]) in the env frame.
"""

from __future__ import annotations

import warp as wp
from newton_lab.kernels.context import TaskContext, base_pose2d

from newton_lab.task_api.cfg import ObsTermCfg, RewardTermCfg
from newton_lab.task_api.terms import term_factory

from .observations import LAST_ACTION
from .rewards import indicator
from .terminations import base_at


def goal_reached(*, goal_xy: tuple[float, float], radius: float):
    """Predicate term: base within ``radius`` [m] of ``goal_xy`` (yaw not checked)."""
    return base_at(goal_xy=goal_xy, radius=radius)


def nav_observations(goal_xy: tuple[float, float]) -> dict[str, ObsTermCfg]:
    """The BaseNav observation: last action, base_xy, goal_xy, vector_to_goal (2 each, env frame [m])."""
    goal = {"goal_xy": tuple(float(v) for v in goal_xy)}
    return {
        "actions": LAST_ACTION,
        "base_xy": ObsTermCfg(func=base_xy_obs, size=2),
        "goal_xy": ObsTermCfg(func=goal_xy_obs, params=goal, size=2),
        "vector_to_goal": ObsTermCfg(func=vector_to_goal_obs, params=goal, size=2),
    }


def nav_rewards(goal_xy: tuple[float, float], radius: float) -> dict[str, RewardTermCfg]:
    """The BaseNav rewards: -distance (weight 2), goal reached (10), squared actions (-0.02)."""
    goal = {"goal_xy": tuple(float(v) for v in goal_xy)}
    return {
        "distance": RewardTermCfg(func=neg_goal_distance, params=goal, weight=2.0),
        "goal_reached": RewardTermCfg(func=indicator(term=goal_reached(goal_xy=goal_xy, radius=radius)), weight=10.0),
        "action_l2": RewardTermCfg(func=action_l2, weight=-0.02),
    }


@wp.func
def base_xy_obs(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
    """Base position (2), env frame [m]."""
    b = base_pose2d(ctx, w)
    out[w, col] = b[0]
    out[w, col + 1] = b[1]


@term_factory()
def goal_xy_obs(*, goal_xy: tuple[float, float]):
    """The goal position (2), env frame [m]."""
    gx, gy = (float(v) for v in goal_xy)

    @wp.func
    def goal_position(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        out[w, col] = gx
        out[w, col + 1] = gy

    return goal_position


@term_factory()
def vector_to_goal_obs(*, goal_xy: tuple[float, float]):
    """Goal minus base position (2), env frame [m]."""
    gx, gy = (float(v) for v in goal_xy)

    @wp.func
    def to_goal(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        b = base_pose2d(ctx, w)
        out[w, col] = gx - b[0]
        out[w, col + 1] = gy - b[1]

    return to_goal


@term_factory()
def neg_goal_distance(*, goal_xy: tuple[float, float]):
    """-|goal - base| [m]."""
    gx, gy = (float(v) for v in goal_xy)

    @wp.func
    def minus_goal_distance(ctx: TaskContext, w: int) -> float:
        b = base_pose2d(ctx, w)
        return -wp.length(wp.vec2(b[0] - gx, b[1] - gy))

    return minus_goal_distance


@wp.func
def action_l2(ctx: TaskContext, w: int) -> float:
    """Sum of squared actions."""
    s = float(0.0)
    for j in range(ctx.actions.shape[1]):
        s += ctx.actions[w, j] * ctx.actions[w, j]
    return s
