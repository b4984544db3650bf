"""The perturbation axes of an evaluation (``newton-lab evaluate --perturb``) and of domain randomisation
(``newton-lab collect --domain-randomize``): what each one changes, in which unit, and its two named levels.
Task-independent: every axis acts on what every task has: the agent's actions and the robot's joints (``acts_on``
``"agent"``, applied by ``newton_lab.agents.perturbed``), the physics of the scene's objects, the cameras, the look
of the fixed surfaces and the light (``"physics"``, ``"camera"``, ``"surface"``, ``"light"``, applied to the env by
``newton_lab.envs.perturb``), and what stands on the table (``"scene"``: the env is built with it). Plain data and
parsing (no Warp, no torch), so that a bad ``--perturb`` is refused before either loads.

Grammar of ``--perturb``: ``AXIS=LEVEL[,AXIS=LEVEL...]`` (one evaluation with those perturbations together; LEVEL
is ``mild``, ``strong`` or a number in the axis's unit), or ``sweep`` (the unperturbed evaluation, then one per
axis and level, each alone: the table of rows a robustness report shows).

Not here: a per-row light (Newton 1.8's ``SensorCamera`` has one light list for all worlds: the light axes change
every row alike, and domain randomisation keeps to the per-row brightness gain of ``randomize``), a per-row field of
view (one ray bundle per resolution), unseen colours (``randomize`` already draws every object and table colour
uniformly), textures of the movable objects (``surface_texture`` patterns the fixed surfaces).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Axis:
    """One perturbation axis: its levels in ``unit``; 0 leaves the evaluation as it is."""

    name: str
    mild: float
    strong: float
    unit: str
    doc: str
    integer: bool = False
    acts_on: str = "agent"
    """What applies it: ``"agent"`` (between the agent and the env), ``"physics"``, ``"camera"``, ``"surface"`` (the
    look of the fixed surfaces) or ``"light"`` (the env, from the evaluation's start), or ``"scene"`` (what the env
    is built with: an evaluation builds an env for it)."""
    scale: bool = False
    """A multiplier: 1 leaves the evaluation as it is, and a level is a number > 0 (else 0 is the neutral level)."""
    per_row: bool = True
    """Domain randomisation can draw it per env row (else one value is every row's)."""
    most: float = float("inf")
    """The largest level there is."""

    @property
    def neutral(self) -> float:
        """The level that changes nothing."""
        return 1.0 if self.scale else 0.0


AXES: dict[str, Axis] = {
    a.name: a
    for a in (
        Axis(
            "action_noise",
            0.02,
            0.05,
            "rad",
            "Gaussian noise of this standard deviation on every joint-target column of the agent's actions (arms, "
            "lift; not grippers, not wheel speeds), drawn anew at every step: a controller that does not track "
            "exactly.",
        ),
        Axis(
            "action_latency",
            1,
            3,
            "steps",
            "the env receives the action the agent chose this many control steps earlier (an episode's first "
            "actions repeat its first): a slower perception and control loop.",
            integer=True,
        ),
        Axis(
            "posture_noise",
            0.05,
            0.15,
            "rad",
            "at every episode's start, before the agent first looks, each joint of the action's joint-target columns "
            "moves from the task's start posture by a uniform offset in [-level, level]: a robot that does not start "
            "where the demos started.",
        ),
        Axis(
            "object_mass",
            1.5,
            3.0,
            "x",
            "the mass and inertia of every movable object of the scene (the task's dynamic entities) are multiplied "
            "by the level: a heavier (> 1) or lighter (< 1) object than the demos lifted.",
            acts_on="physics",
            scale=True,
        ),
        Axis(
            "object_size",
            0.85,
            0.7,
            "x",
            "every shape of every movable object of the scene is scaled about its body by the level (its mass kept: "
            "``object_mass`` is the axis for that): a smaller (< 1) or larger (> 1) object than the demos grasped. "
            "Resets still place each object's centre at the task's height, so a smaller one drops the difference "
            "onto the table in its first steps, and a larger one is pushed up by as much.",
            acts_on="physics",
            scale=True,
        ),
        Axis(
            "friction",
            0.7,
            0.4,
            "x",
            "the sliding friction coefficient of every shape of each row's world (objects, table, the robot's "
            "fingers and pads) is multiplied by the level (the ground's is kept). MuJoCo takes the larger of two "
            "touching shapes' coefficients, so scaling the objects' alone would leave the pads' (1.5) in charge.",
            acts_on="physics",
            scale=True,
        ),
        Axis(
            "distractors",
            1,
            3,
            "objects",
            "this many objects that no term of the task names (a teal can, a white block, a purple block; "
            "``tasks.common.distractors``) stand on the table, each placed at every reset at a spot clear of the "
            "task's objects and of each other. They are movable and collide, so a grasp can knock them. The env is "
            "built with them (``make_env(..., distractors=n)``): an evaluation builds one env per count it asks for.",
            integer=True,
            acts_on="scene",
            per_row=False,
            most=3,
        ),
        Axis(
            "camera_shift",
            2.0,
            5.0,
            "cm",
            "every camera moves this far from its mount pose, in a direction drawn per camera and row (seeded), "
            "and stays there for the evaluation: a camera knocked out of calibration. Reset randomisation already "
            "jitters each view by <= 1 cm.",
            acts_on="camera",
        ),
        Axis(
            "camera_tilt",
            2.0,
            5.0,
            "deg",
            "every camera turns by this angle about an axis drawn per camera and row (seeded), kept for the "
            "evaluation. Reset randomisation already jitters each view by <= 1 deg.",
            acts_on="camera",
        ),
        Axis(
            "camera_fov",
            3.0,
            8.0,
            "deg",
            "every camera's horizontal field of view widens by this angle (the G1's is 47.2 deg; the vertical one "
            "follows, square pixels): another lens. ``cameras.intrinsics`` still reports the calibrated matrix.",
            acts_on="camera",
            per_row=False,
        ),
        Axis(
            "surface_texture",
            10.0,
            3.0,
            "cm",
            "the scene's fixed surfaces (the ground, the table and the other fixed objects; not the movable objects, "
            "not the robot) get a grey checkerboard of squares this wide, multiplied into their colours: a patterned "
            "table cloth and floor the demos never showed. Depth and segmentation are unchanged.",
            acts_on="surface",
            per_row=False,
        ),
        Axis(
            "light_intensity",
            0.6,
            0.3,
            "x",
            "the radiance of the scene's directional light is multiplied by the level (the ambient light is kept): "
            "a dimmer (< 1) or brighter (> 1) room.",
            acts_on="light",
            scale=True,
            per_row=False,
        ),
        Axis(
            "light_direction",
            45.0,
            120.0,
            "deg",
            "the directional light turns by this angle about the vertical (its elevation kept): shading and "
            "highlights from another side.",
            acts_on="light",
            per_row=False,
        ),
    )
}
"""Every axis, by name. Levels: ``mild`` is within what a real cell would see on a good day, ``strong`` beyond."""

LEVELS = ("mild", "strong")


@dataclass(frozen=True)
class Cell:
    """One evaluation of a perturbation table: its label and the value of every perturbed axis."""

    label: str
    values: dict[str, float]
    swept: bool = False
    """Part of a ``sweep`` (an evaluation that cannot apply it, e.g. a camera axis without cameras, skips it)."""


def _value(axis: Axis, level: str, item: str, flag: str = "--perturb") -> float:
    if level in LEVELS:
        return float(getattr(axis, level))
    try:
        value = float(level)
    except ValueError:
        raise ValueError(f"{flag} {item!r}: level {level!r} is not mild, strong or a number [{axis.unit}]") from None
    if axis.scale and not (0 < value < float("inf")):
        raise ValueError(f"{flag} {item!r}: {axis.name} is a factor, a finite number > 0 (1 changes nothing)")
    if not value >= 0 or value != value or value == float("inf"):
        raise ValueError(f"{flag} {item!r}: a level is a finite number >= 0 [{axis.unit}]")
    if axis.integer and value != int(value):
        raise ValueError(f"{flag} {item!r}: {axis.name} takes a whole number of {axis.unit}")
    if value > axis.most:
        raise ValueError(f"{flag} {item!r}: {axis.name} goes up to {axis.most:g} {axis.unit}")
    return value


def parse_cells(text: str) -> list[Cell]:
    """The evaluations ``--perturb text`` asks for (see the module docstring); one-line errors naming the valid
    axes and levels."""
    text = text.strip()
    if text == "sweep":
        return [Cell("none", {})] + [
            Cell(f"{name}={level}", {name: float(getattr(axis, level))}, swept=True)
            for name, axis in AXES.items()
            for level in LEVELS
        ]
    values: dict[str, float] = {}
    for item in (part.strip() for part in text.split(",")):
        name, sep, level = item.partition("=")
        if not sep or not name or not level:
            raise ValueError(
                f"--perturb {item!r}: write AXIS=LEVEL (e.g. action_noise=mild) or sweep; axes: {', '.join(AXES)}"
            )
        if name not in AXES:
            raise ValueError(f"--perturb: unknown axis {name!r}; valid axes: {', '.join(AXES)}")
        if name in values:
            raise ValueError(f"--perturb names {name} twice; give each axis once")
        values[name] = _value(AXES[name], level, item)
    return [Cell(",".join(f"{k}={v:g}" for k, v in values.items()), values)]


RANDOMIZED_KINDS = ("physics", "camera")
"""Kinds of axis domain randomisation draws per env row (the light and the field of view are one for all rows; the
agent's axes would put noise into the demos themselves)."""


def parse_randomization(text: str) -> dict[str, float]:
    """The axes and levels ``--domain-randomize text`` asks for (``AXIS=LEVEL[,AXIS=LEVEL...]``; LEVEL ``mild``,
    ``strong`` or a number in the axis's unit): each row draws its own value up to that level
    (``envs.perturb.randomize_env``). One-line errors naming the axes it takes."""
    flag, usable = "--domain-randomize", [n for n, a in AXES.items() if a.acts_on in RANDOMIZED_KINDS and a.per_row]
    values: dict[str, float] = {}
    for item in (part.strip() for part in text.split(",")):
        name, sep, level = item.partition("=")
        if not sep or not name or not level:
            raise ValueError(f"{flag} {item!r}: write AXIS=LEVEL (e.g. object_mass=mild); axes: {', '.join(usable)}")
        if name not in usable:
            why = "is not an axis" if name not in AXES else "is not drawn per env row"
            raise ValueError(f"{flag}: {name!r} {why}; it takes {', '.join(usable)}")
        if name in values:
            raise ValueError(f"{flag} names {name} twice; give each axis once")
        values[name] = _value(AXES[name], level, item, flag)
    return values
