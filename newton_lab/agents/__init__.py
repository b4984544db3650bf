"""Agents: ``act(env, env_ids=None) -> (num_envs, action_dim)`` actions; agents never step, build or
reset envs. ``PlannerAgent`` executes a task's motion plan for every row at once."""

from .base import BaseAgent, ZeroAgent
from .planner.agent import PlannerAgent
from .policy import PolicyAgent

__all__ = ["BaseAgent", "PlannerAgent", "PolicyAgent", "ZeroAgent"]
