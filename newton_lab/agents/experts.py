"""Expert declarations (``newton_lab.task_api.experts``) -> agents."""

from __future__ import annotations

from ..task_api.experts import Expert, JointTargetExpert, NavExpert, SequenceExpert
from ..task_api.motion_plan import MotionPlan
from .base import BaseAgent
from .joint import JointTargetAgent
from .nav import ProportionalNavAgent, TrajectoryNavAgent
from .planner.agent import PlannerAgent
from .sequence import SequenceAgent, SequenceStep


def agent_for_declaration(expert: Expert) -> BaseAgent:
    """The agent that executes ``expert``."""
    if isinstance(expert, MotionPlan):
        return PlannerAgent(expert)
    if isinstance(expert, NavExpert):
        kwargs = dict(
            success_radius=expert.success_radius,
            yaw_tolerance=expert.yaw_tolerance,
            rotate_before_translate=expert.rotate_before_translate,
        )
        if expert.waypoint_spacing is None:
            return ProportionalNavAgent(expert.goal, expert.goal_yaw, **kwargs)
        return TrajectoryNavAgent(expert.goal, expert.goal_yaw, waypoint_spacing=expert.waypoint_spacing, **kwargs)
    if isinstance(expert, JointTargetExpert):
        return JointTargetAgent(
            expert.targets, max_step=expert.max_step, tolerance=expert.tolerance, hold_steps=expert.hold_steps
        )
    if isinstance(expert, SequenceExpert):
        return SequenceAgent([SequenceStep(name, agent_for_declaration(e)) for name, e in expert.steps])
    raise TypeError(
        f"unknown expert declaration {type(expert).__name__}; use a MotionPlan, NavExpert, "
        "JointTargetExpert or SequenceExpert"
    )
