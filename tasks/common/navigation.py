"""Navigation terms shared by the mobile tasks (BaseNav, the Nav phases of PickToShelf / SortToShelf).

The goal is a task constant, so each task builds its terms with the factories below (Warp closures: the
goal becomes a compile-time constant of the generated ``@wp.func``). Base pose = planar base coordinates
(x, y [m], yaw [rad]) in the env frame.
"""

from __future__ import annotations

import warp as wp

from newton_lab.kernels.context import TaskContext, base_pose2d
from newton_lab.robots.g1 import spec
from newton_lab.task_api.cfg import ActionTermCfg, ObsTermCfg, RewardTermCfg

from .observations import LAST_ACTION


def base_actions(*, clip: bool = True) -> list[ActionTermCfg]:
    """The 4-wheel velocity action [rad/s], clipped to +-4.5 rad/s (= 0.45 m/s) unless ``clip`` is False."""
    lim = spec.WHEEL_VELOCITY_CLIP
    return [ActionTermCfg(name="base_action", group="base", type="velocity", clip=(-lim, lim) if clip else None)]


def make_goal_reached(goal_xy: tuple[float, float], radius: float):
    """``func(ctx, w) -> bool``: base within ``radius`` [m] of ``goal_xy`` (yaw not checked)."""
    gx, gy, r = float(goal_xy[0]), float(goal_xy[1]), float(radius)

    @wp.func
    def goal_reached(ctx: TaskContext, w: int) -> bool:
        b = base_pose2d(ctx, w)
        return wp.length(wp.vec2(b[0] - gx, b[1] - gy)) <= r

    return goal_reached


def nav_observations(goal_xy: tuple[float, float]) -> dict[str, ObsTermCfg]:
    """The BaseNav observation: last action, base_xy, goal_xy, vector_to_goal (2 each, env frame [m])."""
    base_xy, goal_xy_obs, vector_to_goal = make_nav_observations(goal_xy)
    return {
        "actions": LAST_ACTION,
        "base_xy": ObsTermCfg(func=base_xy, size=2),
        "goal_xy": ObsTermCfg(func=goal_xy_obs, size=2),
        "vector_to_goal": ObsTermCfg(func=vector_to_goal, size=2),
    }


def nav_rewards(goal_xy: tuple[float, float], radius: float) -> dict[str, RewardTermCfg]:
    """The BaseNav rewards: -distance (weight 2), goal reached (10), squared actions (-0.02)."""
    neg_distance, goal_reward = make_nav_rewards(goal_xy, radius)
    return {"distance": RewardTermCfg(func=neg_distance, weight=2.0),
            "goal_reached": RewardTermCfg(func=goal_reward, weight=10.0),
            "action_l2": RewardTermCfg(func=action_l2, weight=-0.02)}


def make_nav_observations(goal_xy: tuple[float, float]):
    """Observation terms ``(base_xy, goal_xy, vector_to_goal)``, each 2 wide, env frame [m]."""
    gx, gy = float(goal_xy[0]), float(goal_xy[1])

    @wp.func
    def base_xy(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        b = base_pose2d(ctx, w)
        out[w, col] = b[0]
        out[w, col + 1] = b[1]

    @wp.func
    def goal_xy_obs(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        out[w, col] = gx
        out[w, col + 1] = gy

    @wp.func
    def vector_to_goal(ctx: TaskContext, w: int, out: wp.array2d(dtype=float), col: int):
        b = base_pose2d(ctx, w)
        out[w, col] = gx - b[0]
        out[w, col + 1] = gy - b[1]

    return base_xy, goal_xy_obs, vector_to_goal


def make_nav_rewards(goal_xy: tuple[float, float], radius: float):
    """Reward terms ``(neg_distance, goal_reached)``: -|goal - base| [m] and 1 inside ``radius``."""
    gx, gy, r = float(goal_xy[0]), float(goal_xy[1]), float(radius)

    @wp.func
    def neg_distance(ctx: TaskContext, w: int) -> float:
        b = base_pose2d(ctx, w)
        return -wp.length(wp.vec2(b[0] - gx, b[1] - gy))

    @wp.func
    def goal_reached_reward(ctx: TaskContext, w: int) -> float:
        b = base_pose2d(ctx, w)
        return wp.where(wp.length(wp.vec2(b[0] - gx, b[1] - gy)) <= r, 1.0, 0.0)

    return neg_distance, goal_reached_reward


@wp.func
def action_l2(ctx: TaskContext, w: int) -> float:
    """Sum of squared actions."""
    s = float(0.0)
    for j in range(ctx.actions.shape[1]):
        s += ctx.actions[w, j] * ctx.actions[w, j]
    return s
