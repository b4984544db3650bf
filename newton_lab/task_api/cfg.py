"""Task configuration: what a task declares; ``newton_lab.kernels.fuse`` turns it into kernels."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .physics import PhysicsCfg


@dataclass(kw_only=True)
class EntityCfg:
    """A named rigid object of the scene (a box or cylinder)."""

    name: str
    """The name terms, motion plans and Mimic address the object by."""
    shape: str = "box"
    """``box`` or ``cylinder`` (axis z)."""
    size: tuple[float, float, float]
    """Full extents (x, y, z) [m]; a cylinder's radius is size[0] / 2."""
    pos: tuple[float, float, float]
    """Initial position, env frame [m]."""
    quat: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    """Initial orientation, xyzw."""
    mass: float = 0.0
    """[kg]; used when ``dynamic``."""
    dynamic: bool = True
    """Dynamic bodies get a free joint; others are static colliders (kinematic, gravity off)."""
    color: tuple[float, float, float] = (0.7, 0.7, 0.7)
    """Base colour, RGB in [0, 1] (cameras, rerun)."""
    keep_hue: bool = False
    """The colour names the object (SortToShelf's ``red_cube``): vision randomisation only scales each channel by
    up to +-20 % instead of drawing a new colour, so the object stays recognisable by its colour."""
    friction: float = 1.0
    """Sliding friction coefficient of its collision shape."""


class SceneCfg:
    """A task's rigid objects by name. The env gives each object the slot of its position here, so task
    terms address objects through ``slot(name)`` (a compile-time constant of their ``@wp.func``), never
    through hand-kept numbers."""

    def __init__(self, *entities: EntityCfg):
        names = [e.name for e in entities]
        if len(set(names)) != len(names):
            raise ValueError(f"scene object names must be unique, got {names}")
        self._entities = tuple(entities)
        self.names = tuple(names)

    def slot(self, name: str) -> int:
        """The slot of object ``name`` (index into ``env.buffers.entity_poses``)."""
        if name not in self.names:
            raise ValueError(f"scene has no object {name!r}; objects: {list(self.names)}")
        return self.names.index(name)

    @property
    def entities(self) -> list[EntityCfg]:
        """The objects in slot order (fresh copies: a task may adjust its own)."""
        return [dataclasses.replace(e) for e in self._entities]


@dataclass(kw_only=True)
class ActionTermCfg:
    """One action term: a joint group's columns and how they drive it (the robot binding's action map)."""

    name: str
    """Action term name (a dataset's action columns are named after it and its joints)."""
    group: str
    """Joint group of the task's robot (``RobotBinding.joint_groups``, e.g. the G1's ``left_arm``)."""
    type: str = "absolute"
    """``absolute`` (target = a [rad | m]), ``relative`` (target = current target + a), ``velocity`` (wheel
    speeds [rad/s]) or ``binary`` (gripper master target, 0 open .. 1.2 closed); others are refused."""
    scale: float = 1.0
    """Each column's action is multiplied by this before ``clip``."""
    clip: tuple[float, float] | None = None
    """Bounds of the scaled action (``None``: none)."""


IMAGE_DATA = ("rgb", "depth", "segmentation")
"""What a camera can give, each an image observation ``<camera>_<data>``: RGB uint8 (N, H, W, 3), depth float32
(N, H, W) [m] along the view axis (inf where nothing is hit), segmentation int32 (N, H, W) ids."""


@dataclass(frozen=True, kw_only=True)
class CameraCfg:
    """A camera a task observes through: one of the robot's mounts (the ``TaskCfg.cameras`` key, e.g.
    ``front_head``), rendered in every world at ``width`` x ``height`` with the reference pinhole."""

    width: int = 298
    """Image width [px] (the reference's 298 x 224)."""
    height: int = 224
    """Image height [px]."""
    data: tuple[str, ...] = ("rgb",)
    """Images it gives, of ``IMAGE_DATA``."""


CAMERAS_TEXT = re.compile(r"(\w+)=(\d+)x(\d+)(?::(\w+(?:\+\w+)*))?")
"""One camera of the text form: ``<camera>=<W>x<H>[:<data>+...]``."""


def parse_cameras(value: str) -> dict[str, Any]:
    """The text form of a ``make_env(cameras=...)`` dict (the CLI's ``--cameras``): ``front_head=96x72`` ->
    {"front_head": (96, 72)} [px]; with a data list, ``front_head=96x72:rgb+depth`` -> {"front_head":
    {"resolution": (96, 72), "data": ("rgb", "depth")}}; cameras separated by commas. One-line error if not."""
    found = [CAMERAS_TEXT.fullmatch(part) for part in value.split(",")]
    if not all(found):
        raise ValueError(
            f"--cameras {value!r}: use none, default or <camera>=<W>x<H>[:<data>+...][,...], e.g. "
            f"front_head=96x72 or front_head=96x72:rgb (data: {', '.join(IMAGE_DATA)})"
        )
    names = [m[1] for m in found]
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"--cameras {value!r} names camera {', '.join(twice)} twice; give each camera once")
    return {
        m[1]: (int(m[2]), int(m[3]))
        if m[4] is None
        else {"resolution": (int(m[2]), int(m[3])), "data": tuple(m[4].split("+"))}
        for m in found
    }


def camera_option(value: str | None) -> bool | dict[str, Any] | None:
    """A ``make_env(cameras=...)`` value from its text form (``--cameras``): ``default`` -> None (the task's
    cameras), ``none`` -> False (no rendering), else ``parse_cameras(value)``; a bad spelling raises a one-line
    error."""
    return None if value in (None, "default") else False if value == "none" else parse_cameras(value)


ACTION_DIM = "action_dim"
"""Observation width the env derives: the task's action columns."""
ROBOT_COORDS = "robot_coords"
"""Observation width the env derives: the robot's joint coordinates."""
ARM_JOINTS = "arm_joints"
"""Observation width the env derives: the controlled arm's joints."""
DERIVED_SIZES = (ACTION_DIM, ROBOT_COORDS, ARM_JOINTS)

DIVERGED = "diverged"
"""Termination reason of a row whose simulation diverged (non-finite or absurd body state, see
``TaskCfg.max_body_distance``); ``collect`` drops such episodes and counts them."""
BUILTIN_TERMINATION_REASONS = ("none", "success", "time_out", DIVERGED)
"""Names of the reason codes the fused task kernel writes before the task's failure terms
(``newton_lab.kernels.fuse.REASON_NONE`` .. ``REASON_DIVERGED``; failure term ``i`` is code
``FIRST_FAILURE_REASON + i``)."""


@dataclass(frozen=True, kw_only=True)
class TermCfg:
    """A task term: a ``@wp.func`` the task kernels call, or a generic term with its ``params``
    (``newton_lab.task_api.terms``). Events: ``func(ctx, w, seed, stream, randomize)`` at reset; signals:
    ``func(ctx, w) -> bool`` recorded every step."""

    func: Callable
    """A ``@wp.func``, a ``@term_factory`` (with ``params``) or a bound ``Term``."""
    params: dict[str, Any] = field(default_factory=dict)
    """A generic term's parameters by name: scene objects by their names (``{"entity": "cube"}``) and
    constants; the env resolves the names to slots and bakes everything into the compiled term."""


@dataclass(frozen=True, kw_only=True)
class ObsTermCfg(TermCfg):
    """An observation term: ``func(ctx, w, out, col)`` writes ``size`` columns from ``col``."""

    size: int | str
    """Columns written: a fixed count of the value's own (7 for a pose, 3 for a position) or a width the env
    derives from the robot and the action map (``ACTION_DIM``, ``ROBOT_COORDS``, ``ARM_JOINTS``)."""
    privileged: bool = False
    """The term reads what a real robot does not measure (a scene object's pose, a target's position): the task
    option ``obs_mode="sensors"`` drops it, leaving proprioception and cameras."""


@dataclass(frozen=True, kw_only=True)
class RewardTermCfg(TermCfg):
    """A reward term ``func(ctx, w) -> float``; the step reward is the weighted sum."""

    weight: float = 1.0
    """Factor of the term in the step reward."""


@dataclass(frozen=True, kw_only=True)
class TerminationTermCfg(TermCfg):
    """A failure term ``func(ctx, w) -> bool``; it ends the episode (reason = its name)."""

    phase: int = -1
    """Phase the term is limited to (``-1``: every phase)."""


@dataclass(kw_only=True)
class PhaseCfg:
    """One phase of a multi-phase (coherent) task; see ``newton_lab.task_api.compose``."""

    name: str
    """Phase name (``pick``, ``nav``, ``place``): the per-phase summary and phase policies use it."""
    task_id: str | None = None
    """The component task this phase runs (its success ends the phase), if any."""
    action_groups: tuple[str, ...] | None = None
    """Joint groups whose action columns this phase commands; the others hold. ``None``: all."""
    fixed_base: bool = False
    """Zero base twist during this phase, whatever the wheel columns say."""
    kind: str | None = None
    """What the phase does when several phases do the same to different objects (SortToShelf-All's ``pick_1`` ..
    ``pick_4`` are ``pick``); ``None``: its name."""
    target_option: str | None = None
    """The component option whose value differs per row (SortToShelf-All's ``sorting_object``): the coherent
    task's observation term of that name holds each row's value one-hot over the option's choices, and the
    phase's expert is the component's expert for each value, switched per row. ``None``: the task's options."""


@dataclass(kw_only=True)
class TaskCfg:
    """Everything a task declares. Thresholds live as constants inside its ``@wp.func`` terms."""

    task_id: str = ""
    """The task id; the registry fills it from ``TaskSpec.id`` (a task writes its id once, in its spec)."""
    entities: list[EntityCfg]
    """The scene's rigid objects in slot order (``SceneCfg.entities``); terms name them."""
    actions: list[ActionTermCfg]
    """Action terms in column order."""
    observations: dict[str, ObsTermCfg]
    """Observation terms by name, in column order."""
    phase_success: list[Callable]
    """One success predicate per phase (single-phase tasks list one): a ``@wp.func (ctx, w) -> bool`` or a
    generic term bound to its parameters (``common.terminations.held(...)``, ``grasped(entity="cube")``)."""
    terminations: dict[str, TerminationTermCfg] = field(default_factory=dict)
    """Failure terms by name (the name is the termination reason)."""
    phases: list[PhaseCfg] = field(default_factory=list)
    """Phase declarations matching ``phase_success`` (empty: one phase owning every action column)."""
    rewards: dict[str, RewardTermCfg] = field(default_factory=dict)
    """Reward terms by name; the step reward is their weighted sum."""
    signals: dict[str, TermCfg] = field(default_factory=dict)
    """Subtask signals recorded every step (Mimic segments on them)."""
    events: dict[str, TermCfg] = field(default_factory=dict)
    """Reset events, run in order after a row's defaults are restored."""
    posture: dict[str, float] = field(default_factory=dict)
    """Initial joint values by name; unnamed joints start at 0 [rad | m]."""
    initial_targets: dict[str, float] = field(default_factory=dict)
    """Drive targets at reset that differ from the initial positions (e.g. a gripper commanded closed on a
    held object while its fingers rest on it) [rad | m]; applied after ``posture`` and ``scenario``."""
    root_pos: tuple[float, float, float] = (-1.0, 0.0, 0.0)
    """Robot root position at reset, env frame [m]."""
    root_yaw: float = 0.0
    """Robot root yaw at reset [rad]."""
    fixed_base: bool = True
    """Base twist held at zero (manipulation tasks); mobile tasks drive it from their wheel columns."""
    scenario: str | None = None
    """Reset overlay (``newton_lab.envs.scenario``): a YAML path or ``package:file.yaml`` resource."""
    robot: str = "g1"
    """The robot the task runs on, by registry name (``newton_lab.robots.registry.robot_binding``): the env builds
    its model and reads its joint groups, arms, TCP, gripper range and camera mounts from it (``env.robot``)."""
    arm: str = "left"
    """The controlled arm (``left`` or ``right``): the TCP, gripper and arm coordinates terms read."""
    arm_home: tuple[float, ...] = ()
    """Reference posture of the controlled arm for carry / retract predicates (``ctx.arm_home``) [rad], one value
    per joint of the arm; empty: every joint at 0."""
    command_dim: int = 0
    """Columns of the per-row task command (``ctx.command``, e.g. a Reach goal written by a reset event)."""
    hold_slots: int = 1
    """Per-row consecutive-step counters (``ctx.hold``). Derived: resolving the terms sizes it to the counters
    that ``held(...)`` terms ask for; a task does not set it."""
    episode_length_s: float = 3600.0
    """Episode time limit [s]; ``max_episode_steps`` = this / ``control_dt`` (time-out truncates)."""
    sim_dt: float = 0.01
    """Physics step [s]."""
    decimation: int = 5
    """Physics steps per control step (control at 1 / (sim_dt * decimation) Hz)."""
    physics: PhysicsCfg = field(default_factory=PhysicsCfg)
    """Solver options, contact / constraint capacities and the robot's contact filter (``task_api.physics``);
    the default is what every task ran with before tasks chose their own."""
    terminate_on_success: bool = True
    """End the episode when the last phase succeeds (``False``: success is latched, e.g. for an operator who
    ends the episode)."""
    max_body_distance: float = 50.0
    """Divergence guard: a body farther than this from its env origin ends the row (reason ``diverged``) [m]."""
    max_body_linear_speed: float = 100.0
    """Divergence guard: a body moving faster than this ends the row (reason ``diverged``) [m/s]."""
    max_body_angular_speed: float = 1000.0
    """Divergence guard: a body spinning faster than this ends the row (reason ``diverged``) [rad/s]. Non-finite
    body poses, velocities, joint coordinates or joint velocities always do."""
    cameras: dict[str, CameraCfg] = field(default_factory=dict)
    """Cameras by robot mount name (``RobotBinding`` camera mounts, e.g. the G1's ``front_head``); empty: a state-only
    task. ``make_env(..., cameras=...)`` turns them off or changes their resolution."""
    options: dict[str, Any] = field(default_factory=dict)
    """The task options this cfg was built with (recorded in dataset env_args)."""

    @property
    def control_dt(self) -> float:
        """Control period: ``sim_dt * decimation`` [s]."""
        return self.sim_dt * self.decimation

    @property
    def max_episode_steps(self) -> int:
        """Episode step limit [control steps]."""
        return int(round(self.episode_length_s / self.control_dt))

    @property
    def phase_names(self) -> list[str]:
        """Phase names (``["task"]`` for a single-phase task)."""
        return [p.name for p in self.phases] if self.phases else ["task"]

    @property
    def phase_kinds(self) -> dict[str, list[int]]:
        """Phase indices by kind (``PhaseCfg.kind``, else the phase's name), kinds in first-phase order: what the
        split writes one dataset for and a phase policy runs (``{"task": [0]}`` for a single-phase task)."""
        kinds: dict[str, list[int]] = {}
        for i, p in enumerate(self.phases):
            kinds.setdefault(p.kind or p.name, []).append(i)
        return kinds or {"task": [0]}

    @property
    def target_observations(self) -> list[str]:
        """Observation terms a phase policy must see besides its sensors: the per-row target of its phases
        (``PhaseCfg.target_option``, e.g. SortToShelf-All's ``sorting_object`` one-hot), in first-phase order."""
        return list(dict.fromkeys(p.target_option for p in self.phases if p.target_option))

    @property
    def divergence_bounds(self) -> tuple[float, float, float]:
        """(max body distance [m], linear speed [m/s], angular speed [rad/s]) the task kernel guards."""
        return (float(self.max_body_distance), float(self.max_body_linear_speed), float(self.max_body_angular_speed))

    @property
    def termination_reasons(self) -> list[str]:
        """Reason names indexed by the codes the task kernel writes."""
        return [*BUILTIN_TERMINATION_REASONS, *self.terminations]
