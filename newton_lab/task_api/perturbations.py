"""The perturbation axes of an evaluation (``newton-lab evaluate --perturb``): what each one changes, in which
unit, and its two named levels. Task-independent: every axis acts on the robot's joints or on the agent's actions,
which every task has. Plain data and parsing (no Warp, no torch), so that a bad ``--perturb`` is refused before
either loads; ``newton_lab.agents.perturbed`` applies them.

Grammar of ``--perturb``: ``AXIS=LEVEL[,AXIS=LEVEL...]`` (one evaluation with those perturbations together; LEVEL
is ``mild``, ``strong`` or a number in the axis's unit), or ``sweep`` (the unperturbed evaluation, then one per
axis and level, each alone: the table of rows a robustness report shows).
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
    )
}
"""Every axis, by name. Levels: ``mild`` is within what a real cell would see on a good day, ``strong`` beyond."""

LEVELS = ("mild", "strong")


@dataclass(frozen=True)
class Cell:
    """One evaluation of a perturbation table: its label and the value of every perturbed axis."""

    label: str
    values: dict[str, float]


def _value(axis: Axis, level: str, item: str) -> float:
    if level in LEVELS:
        return float(getattr(axis, level))
    try:
        value = float(level)
    except ValueError:
        raise ValueError(f"--perturb {item!r}: level {level!r} is not mild, strong or a number [{axis.unit}]") from None
    if not value >= 0 or value != value or value == float("inf"):
        raise ValueError(f"--perturb {item!r}: a level is a finite number >= 0 [{axis.unit}]")
    if axis.integer and value != int(value):
        raise ValueError(f"--perturb {item!r}: {axis.name} takes a whole number of {axis.unit}")
    return value


def parse_cells(text: str) -> list[Cell]:
    """The evaluations ``--perturb text`` asks for (see the module docstring); one-line errors naming the valid
    axes and levels."""
    text = text.strip()
    if text == "sweep":
        return [Cell("none", {})] + [
            Cell(f"{name}={level}", {name: float(getattr(axis, level))})
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
