"""Expert declarations: what a task's scripted expert does, as data.

A task's ``TaskSpec.expert(**options)`` returns one of these; ``newton_lab.agents.agent_for_declaration`` builds
the agent. Tasks declare experts without importing the agents layer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .motion_plan import MotionPlan, plan_from_yaml


@dataclass(frozen=True, kw_only=True)
class NavExpert:
    """Drive the base to ``goal`` (reference nav control law; ``newton_lab.agents.nav``)."""

    goal: tuple[float, float]
    """Goal base position, env frame [m]."""
    goal_yaw: float | None = None
    """Goal base yaw [rad]; ``None``: any heading."""
    success_radius: float = 0.15
    """xy velocity is zero inside this distance of the goal [m]."""
    yaw_tolerance: float = 0.03
    """Yaw rate is zero inside this error [rad]."""
    rotate_before_translate: bool = True
    waypoint_spacing: float | None = None
    """Straight-line waypoints this far apart [m] (trajectory following); ``None`` heads straight for the
    goal every step (proportional drive)."""


@dataclass(frozen=True, kw_only=True)
class JointTargetExpert:
    """Ramp named joints to fixed targets (``newton_lab.agents.JointTargetAgent``)."""

    targets: dict[str, float]
    """Joint name -> target [rad | m]."""
    max_step: float | None = None
    """Largest target move per control step [rad | m]; ``None`` jumps."""
    tolerance: float = 0.12
    """Done when every joint is within this of its target [rad | m]."""
    hold_steps: int = 1
    """... for this many consecutive steps."""


@dataclass(frozen=True, kw_only=True)
class SequenceExpert:
    """Named experts run one after the other per row (``newton_lab.agents.SequenceAgent``)."""

    steps: tuple[tuple[str, Expert], ...] = field(default_factory=tuple)


Expert = MotionPlan | NavExpert | JointTargetExpert | SequenceExpert
"""Any expert declaration."""


def yaml_plan(path: str | Path) -> Callable[..., MotionPlan]:
    """An expert factory reading the YAML motion plan at ``path`` (options ignored)."""
    path = Path(path)

    def load(**_options) -> MotionPlan:
        return plan_from_yaml(path.read_text())

    return load
