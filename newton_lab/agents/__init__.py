"""Agents: ``act(env, env_ids=None) -> (num_envs, action_dim)`` actions; agents never step, build or
reset envs. ``PlannerAgent`` executes a task's motion plan for every row at once; nav agents drive the
base; ``SequenceAgent`` and ``TaskFlowAgent`` compose agents per row."""

from .base import BaseAgent, ZeroAgent
from .joint import JointTargetAgent
from .nav import BaseNavAgent, GoalNavAgent, ProportionalNavAgent, TrajectoryNavAgent
from .planner.agent import PlannerAgent
from .policy import PolicyAgent
from .sequence import SequenceAgent, SequenceStep
from .task_flow import TaskFlowAgent, default_agent, expert_agent

__all__ = [
    "BaseAgent",
    "BaseNavAgent",
    "GoalNavAgent",
    "JointTargetAgent",
    "PlannerAgent",
    "PolicyAgent",
    "ProportionalNavAgent",
    "SequenceAgent",
    "SequenceStep",
    "TaskFlowAgent",
    "TrajectoryNavAgent",
    "ZeroAgent",
    "default_agent",
    "expert_agent",
]
