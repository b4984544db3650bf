"""Physics settings a task declares (``TaskCfg.physics``): the MuJoCo-Warp solver's options, its contact and
constraint capacities, and which robot geoms may collide with what.

The defaults are the solver every task ran with before tasks could choose (Newton solver, elliptic cone, 20
iterations, 10 line-search iterations, every robot collision geom against every scene object and the ground),
with the robot's idle joints welded (``weld_idle_joints``: the measured lever). A task that declares cheaper
settings justifies them by a measurement: steps/s gained and the expert's success kept (``tools/physics_table.py``
prints both side by side; benchmarks history, "Per-task physics settings").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

ANY_OBJECT = "*"
"""In a ``ContactFilterCfg`` target list: every scene object (``TaskCfg.entities``) of the task."""
GROUND = "ground"
"""In a ``ContactFilterCfg`` target list: the ground plane shared by all worlds."""
CONES = ("elliptic", "pyramidal")


@dataclass(frozen=True, kw_only=True)
class ContactFilterCfg:
    """Which robot geoms may collide with what. The robot's collision geoms are grouped by its link groups
    (``RobotBinding.link_groups`` without the ``robot/`` prefix; the G1's: ``base``, ``torso``, ``head``,
    ``left_arm``, ``left_gripper`` (link7's palm and the fingers), ``right_arm``, ``right_gripper``). A group may
    touch only the targets listed for it; a group not listed touches nothing. Scene objects keep colliding with
    each other and the ground as without a filter, and robot geoms never collide with each other (self-collisions
    are off for the G1).

    The env turns the filter into Newton collision filter pairs on the model builder
    (``ModelBuilder.add_shape_collision_filter_pair``); ``SolverMuJoCo`` compiles them into MuJoCo's
    ``contype`` / ``conaffinity`` masks and body excludes, so a filtered pair never reaches MuJoCo-Warp's
    broad phase and never makes a contact."""

    robot: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    """Robot collision group -> the targets it may collide with: scene object names, ``ANY_OBJECT`` (``"*"``,
    every scene object) and ``GROUND`` (``"ground"``). Unknown group or object names raise when the env is
    built."""

    def allows(self, group: str, target: str) -> bool:
        """Whether geoms of robot group ``group`` may collide with ``target`` (a scene object name or ``GROUND``)."""
        targets = self.robot.get(group, ())
        return target in targets or (target != GROUND and ANY_OBJECT in targets)


def gripper_only(*groups: str, ground: bool = False) -> ContactFilterCfg:
    """A filter in which only the robot groups ``groups`` (default the G1's ``left_gripper``: palm and fingers)
    collide, each with every scene object (and the ground with ``ground``); every other robot geom collides with
    nothing."""
    targets = (ANY_OBJECT, GROUND) if ground else (ANY_OBJECT,)
    return ContactFilterCfg(robot={g: targets for g in (groups or ("left_gripper",))})


@dataclass(frozen=True, kw_only=True)
class PhysicsCfg:
    """The solver options, capacities, contact filter and welded joints of a task's physics (``SolverMuJoCo``;
    MuJoCo-Warp, the Newton solver, implicitfast integration)."""

    iterations: int = 20
    """Maximum constraint-solver iterations per physics step. A world stops early once its cost improves by less
    than ``tolerance``; on the GPU the solve runs while any world is still iterating, on the CPU every
    iteration's kernels are launched."""
    ls_iterations: int = 10
    """Maximum line-search iterations per solver iteration (a compile-time constant of MuJoCo-Warp's line
    search: another value compiles another solver module). A truncated line search degrades the solve: with 5,
    SortToShelf's green_cylinder expert fell from 16/16 to 12/16."""
    tolerance: float | None = None
    """Relative cost improvement below which a world's solve stops; ``None``: MuJoCo's default (1e-8)."""
    ls_tolerance: float | None = None
    """Line-search tolerance; ``None``: MuJoCo's default (0.01)."""
    cone: str = "elliptic"
    """Friction cone: ``elliptic`` (exact Coulomb cone; what the grasps were tuned with) or ``pyramidal``
    (linearised, cheaper per contact, more constraint rows)."""
    impratio: float = 10.0
    """Frictional-to-normal constraint impedance ratio (elliptic cones; > 1 makes grasps slip less)."""
    contacts_per_world: int | None = None
    """MuJoCo contact capacity per world (``nconmax``); ``None`` keeps Newton's default. Size it from measured
    peak contact counts (the solver's ``mjw_data.nacon`` over expert runs): oversized capacities slow every
    step."""
    constraints_per_world: int | None = None
    """MuJoCo constraint-row capacity per world (``njmax``); ``None`` keeps Newton's default (64 rows for the
    G1 scenes)."""
    contact_filter: ContactFilterCfg | None = None
    """Which robot geoms may collide with what; ``None``: every robot collision geom with every scene object and
    the ground."""
    weld_idle_joints: bool = True
    """Weld every robot joint that no action term drives at its reset value (posture, scenario), and merge the
    links it held into their parents, so the solver integrates only the driven joints (and the joints coupled to
    them, a gripper's fingers; the planar base stays free unless ``TaskCfg.fixed_base``). The env keeps the full
    robot's layout: a welded joint reads its reset value and zero velocity (``envs.drive``). A welded joint
    is rigid where its drive would give a little under load, and a reset must not move it (the env refuses one
    that does, when it is built). On the 2-core CPU, env-steps/s at 4 envs: PickCube 3.11x, StackCube 1.44x,
    PickToShelf 1.73x, SortToShelf 1.44x, Reach 5.72x, BaseNav 7.90x, every expert's success unchanged
    (``tools/physics_table.py --variant weld_idle_joints=False``). ``False``: every robot joint is simulated,
    held by its drive."""

    sync_every_substep: bool = False
    """Exchange the state with MuJoCo-Warp around every physics substep (Newton's ``SolverMuJoCo.step`` each
    substep). ``False``: once a control step, push before the first substep and pull after the last
    (``envs.mujoco_substeps``), the same physics in fewer launches (the wheel drive reads each substep's yaw
    from MuJoCo-Warp's coordinates): PickCube 1.13x at 4096 envs on an H100."""

    def __post_init__(self) -> None:
        if self.cone not in CONES:
            raise ValueError(f"physics cone {self.cone!r} is not one of {CONES}")
        if self.iterations < 1 or self.ls_iterations < 1:
            raise ValueError(
                f"physics iterations and ls_iterations must be >= 1, got {self.iterations}, {self.ls_iterations}"
            )

    def solver_options(self) -> dict:
        """The ``newton.solvers.SolverMuJoCo`` keyword arguments of these settings."""
        return dict(
            use_mujoco_cpu=False,
            solver="newton",
            integrator="implicitfast",
            cone=self.cone,
            iterations=self.iterations,
            ls_iterations=self.ls_iterations,
            tolerance=self.tolerance,
            ls_tolerance=self.ls_tolerance,
            impratio=self.impratio,
            nconmax=self.contacts_per_world,
            njmax=self.constraints_per_world,
        )


def merged(physics: list[PhysicsCfg]) -> PhysicsCfg:
    """One physics for a coherent task from its phases': the most iterations, the tightest tolerances, the
    largest capacities, an elliptic cone if any phase has one, a filter allowing what any phase allows (no
    filter if a phase has none), and welding only if every phase welds (the coherent task's own action terms
    then say which joints are driven)."""
    first = physics[0]
    filters = [p.contact_filter for p in physics]
    contact_filter = None
    if all(f is not None for f in filters):
        robot: dict[str, tuple[str, ...]] = {}
        for f in filters:
            for group, targets in f.robot.items():
                robot[group] = tuple(dict.fromkeys((*robot.get(group, ()), *targets)))
        contact_filter = ContactFilterCfg(robot=robot)

    def tightest(values):
        given = [v for v in values if v is not None]
        return min(given) if len(given) == len(values) else None

    def largest(values):
        return max((v or 0) for v in values) or None

    return PhysicsCfg(
        iterations=max(p.iterations for p in physics),
        ls_iterations=max(p.ls_iterations for p in physics),
        tolerance=tightest([p.tolerance for p in physics]),
        ls_tolerance=tightest([p.ls_tolerance for p in physics]),
        cone="elliptic" if any(p.cone == "elliptic" for p in physics) else first.cone,
        impratio=max(p.impratio for p in physics),
        contacts_per_world=largest([p.contacts_per_world for p in physics]),
        constraints_per_world=largest([p.constraints_per_world for p in physics]),
        contact_filter=contact_filter,
        weld_idle_joints=all(p.weld_idle_joints for p in physics),
        sync_every_substep=any(p.sync_every_substep for p in physics),
    )
