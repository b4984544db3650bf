"""GalbotG1-BaseNav-v0 configuration (as on the reference platform): drive the mobile base from A=(0, 0) to B=(2, 0)."""

from __future__ import annotations

from newton_lab.tasks.common import navigation as nav
from newton_lab.tasks.common.config.g1.setup import base_actions

from newton_lab.task_api.cfg import TaskCfg, TermCfg
from newton_lab.task_api.experts import NavExpert

GOAL_XY = (2.0, 0.0)
"""Goal position, env frame [m]."""
GOAL_YAW = 0.0
SUCCESS_RADIUS = 0.15
"""Base within this distance of the goal ends the episode [m]."""

_goal_reached = nav.goal_reached(goal_xy=GOAL_XY, radius=SUCCESS_RADIUS)


def base_nav_cfg() -> TaskCfg:
    """Mobile G1 at the origin, no objects; 4-wheel velocity action (clip +-4.5 rad/s); 12 s episodes."""
    return TaskCfg(
        entities=[],
        actions=base_actions(),
        observations=nav.nav_observations(GOAL_XY),
        phase_success=[_goal_reached],
        rewards=nav.nav_rewards(GOAL_XY, SUCCESS_RADIUS),
        signals={"goal_reached": TermCfg(func=_goal_reached)},
        root_pos=(0.0, 0.0, 0.0),
        fixed_base=False,
        episode_length_s=12.0,
    )


def nav_expert() -> NavExpert:
    """The expert: proportional drive to the goal (speed cap 0.45 m/s)."""
    return NavExpert(goal=GOAL_XY, goal_yaw=None, success_radius=SUCCESS_RADIUS)
