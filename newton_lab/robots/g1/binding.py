"""The G1 bound to a built scene: ``robots.bound.BoundRobot`` with the G1's facts (``robots.g1.robot.G1``).

The env binds whatever robot its task config names (``BoundRobot.from_layout(env.robot, ...)``); this module keeps
the G1's own entry point, ``G1Binding.from_layout(layout, actions=..., arm=...)``, and the names it always had.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ..bound import ACTION_KINDS, UNSET_VELOCITY_LIMIT, ActionMap, BoundRobot, DriveLimits, RobotContext
from . import spec
from .robot import G1, GROUP_KINDS

__all__ = ["ACTION_KINDS", "GROUP_KINDS", "UNSET_VELOCITY_LIMIT", "ActionMap", "DriveLimits", "G1Binding",
           "RobotContext"]


class G1Binding(BoundRobot):
    """The G1 on one built scene (see ``BoundRobot``)."""

    @classmethod
    def from_layout(cls, layout: Any, *, actions: Sequence[Any], arm: str = spec.DEFAULT_ARM) -> G1Binding:
        """Bind the G1 of ``layout`` (``envs.scene.SceneLayout``) with the task's action terms and arm."""
        bound = BoundRobot.from_layout(G1, layout, actions=actions, arm=arm)
        return cls(robot=G1, context=bound.context, actions=bound.actions, limits=bound.limits)
