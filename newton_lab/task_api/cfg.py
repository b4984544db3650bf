"""Task configuration: what a task declares; ``newton_lab.kernels.fuse`` turns it into kernels."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable


@dataclass(kw_only=True)
class EntityCfg:
    """A named rigid object of the scene (a box or cylinder)."""

    name: str
    shape: str = "box"
    """``box`` or ``cylinder`` (axis z)."""
    size: tuple[float, float, float]
    """Full extents (x, y, z) [m]; a cylinder's radius is size[0] / 2."""
    pos: tuple[float, float, float]
    """Initial position, env frame [m]."""
    quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    mass: float = 0.0
    """[kg]; used when ``dynamic``."""
    dynamic: bool = True
    """Dynamic bodies get a free joint; others are static colliders (kinematic, gravity off)."""
    color: tuple[float, float, float] = (0.7, 0.7, 0.7)
    friction: float = 1.0


@dataclass(kw_only=True)
class ActionTermCfg:
    """One action term: a joint group driven by position or velocity targets."""

    name: str
    group: str
    """Joint group of ``newton_lab.robots.g1.spec.JOINT_GROUPS``."""
    type: str = "absolute"
    """``absolute`` (position targets), ``velocity`` (velocity targets) or ``binary`` (gripper)."""
    clip: tuple[float, float] | None = None


@dataclass(kw_only=True)
class ObsTermCfg:
    """One observation term: ``func(ctx, w, out, col)`` writes ``dim`` values from column ``col``."""

    name: str
    func: Callable
    dim: int


@dataclass(kw_only=True)
class PhaseCfg:
    """One phase of a multi-phase (coherent) task; see ``newton_lab.task_api.compose``."""

    name: str
    task_id: str | None = None
    """The component task this phase runs (its success ends the phase), if any."""
    action_groups: tuple[str, ...] | None = None
    """Joint groups whose action columns this phase commands; the others hold. ``None``: all."""
    fixed_base: bool = False
    """Zero base twist during this phase, whatever the wheel columns say."""


@dataclass(kw_only=True)
class TaskCfg:
    """Everything a task declares. Thresholds live as constants inside its ``@wp.func`` terms."""

    task_id: str
    entities: list[EntityCfg]
    actions: list[ActionTermCfg]
    observations: list[ObsTermCfg]
    phase_success: list[Callable]
    """One success predicate per phase (single-phase tasks list one)."""
    terminations: dict[str, Callable] = field(default_factory=dict)
    """Failure terms ``name -> func(ctx, w) -> bool``."""
    termination_phase: dict[str, int] = field(default_factory=dict)
    """Phase a failure term is limited to (unnamed terms apply in every phase)."""
    phases: list[PhaseCfg] = field(default_factory=list)
    """Phase declarations matching ``phase_success`` (empty: one phase owning every action column)."""
    rewards: dict[str, tuple[Callable, float]] = field(default_factory=dict)
    signals: dict[str, Callable] = field(default_factory=dict)
    """Subtask signals recorded every step (Mimic segments on them)."""
    events: list[Callable] = field(default_factory=list)
    """Reset events ``func(ctx, w, seed, stream, randomize)``."""
    posture: dict[str, float] = field(default_factory=dict)
    """Initial joint values by name; unnamed joints start at 0 [rad | m]."""
    initial_targets: dict[str, float] = field(default_factory=dict)
    """Drive targets at reset that differ from the initial positions (e.g. a gripper commanded closed on a
    held object while its fingers rest on it) [rad | m]; applied after ``posture`` and ``scenario``."""
    root_pos: tuple[float, float, float] = (-1.0, 0.0, 0.0)
    root_yaw: float = 0.0
    fixed_base: bool = True
    """Base twist held at zero (manipulation tasks); mobile tasks drive it from their wheel columns."""
    scenario: str | None = None
    """Reset overlay (``newton_lab.envs.scenario``): a YAML path or ``package:file.yaml`` resource."""
    arm: str = "left"
    arm_home: tuple[float, ...] = (0.0,) * 7
    command_dim: int = 0
    hold_slots: int = 1
    episode_length_s: float = 3600.0
    sim_dt: float = 0.01
    """Physics step [s]."""
    decimation: int = 5
    """Physics steps per control step (control at 1 / (sim_dt * decimation) Hz)."""
    contacts_per_world: int | None = None
    """MuJoCo contact capacity per world (``nconmax``); ``None`` keeps Newton's default. Size it from
    measured peak contact counts (``NewtonEnv.peak_contacts``): oversized capacities slow every step."""
    constraints_per_world: int | None = None
    """MuJoCo constraint-row capacity per world (``njmax``); ``None`` keeps Newton's default."""
    terminate_on_success: bool = True
    options: dict[str, Any] = field(default_factory=dict)
    """The task options this cfg was built with (recorded in dataset env_args)."""

    @property
    def control_dt(self) -> float:
        return self.sim_dt * self.decimation

    @property
    def max_episode_steps(self) -> int:
        return int(round(self.episode_length_s / self.control_dt))

    @property
    def phase_names(self) -> list[str]:
        return [p.name for p in self.phases] if self.phases else ["task"]

    @property
    def termination_reasons(self) -> list[str]:
        """Reason names indexed by the codes the task kernel writes."""
        return ["none", "success", "time_out", *self.terminations]
