"""Agents: ``act(env, env_ids=None) -> (num_envs, action_dim)`` actions; agents never step, build or
reset envs. ``PlannerAgent`` executes a task's motion plan for every row at once; nav agents drive the
base; ``SequenceAgent`` and ``TaskFlowAgent`` compose agents per row; ``TeleopAgent`` maps an operator's device;
``PerturbedAgent`` evaluates any of them under action noise, latency and start-posture noise."""

from .base import BaseAgent, ZeroAgent
from .experts import (
    JointTargetAgent,
    SequenceAgent,
    SequenceStep,
    TargetSwitchAgent,
    TaskFlowAgent,
    agent_for_declaration,
    expert_agent,
)
from .nav import BaseNavAgent, GoalNavAgent, ProportionalNavAgent, TrajectoryNavAgent
from .perturbed import PerturbedAgent, evaluate_perturbed, perturbation_table
from .planner.agent import PlannerAgent
from .teleop import TeleopAgent

__all__ = [
    "BaseAgent",
    "BaseNavAgent",
    "GoalNavAgent",
    "JointTargetAgent",
    "PerturbedAgent",
    "PlannerAgent",
    "ProportionalNavAgent",
    "SequenceAgent",
    "SequenceStep",
    "TargetSwitchAgent",
    "TaskFlowAgent",
    "TeleopAgent",
    "TrajectoryNavAgent",
    "ZeroAgent",
    "agent_for_declaration",
    "evaluate_perturbed",
    "expert_agent",
    "perturbation_table",
]
