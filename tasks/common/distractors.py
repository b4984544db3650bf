"""Distractor objects: things on the table that no phase, reward or success term names, for a policy to ignore.

``with_distractors(cfg, n)`` adds the first ``n`` of ``DISTRACTORS`` to a task with a static ``table``: each is a
dynamic object (it collides with the robot's colliding links, the table and the task's objects, and can be pushed
over), placed at every reset at a spot of the table top clear of the task's objects and of the distractors placed
before it (``events.scatter_on``). They come after the task's own objects, so every slot a term reads stays as it
was; the observations, actions and phases are the task's. ``make_env(..., distractors=n)`` builds a task with them,
and the ``distractors`` perturbation axis (``task_api.perturbations``) evaluates under them.

Their colours are none of the tasks' object colours (red, blue, yellow, green, the shelves' greys) and keep their hue
under ``--randomize`` (``EntityCfg.keep_hue``), so that they look alike in every episode and never like an object a
colour-named task asks for.
"""

from __future__ import annotations

import dataclasses

from newton_lab.task_api.cfg import EntityCfg, TaskCfg, TermCfg
from newton_lab.task_api.physics import PhysicsCfg

from .events import scatter_on

PARK_POS = (1.5, 1.5)
"""Where a distractor is built (x, y, on the ground) [m]: out of reach and of view until its reset event puts it on
the table; a model built with distractors starts its first episode with them placed, like every later one."""


def _distractor(k: int, size, mass: float, color, shape: str = "box") -> EntityCfg:
    """Distractor ``k``: a movable object whose colour keeps its hue under ``--randomize`` (``with_distractors`` sets
    its build position)."""
    return EntityCfg(
        name=f"distractor_{k}", shape=shape, size=size, pos=(0, 0, 0), mass=mass, color=color, keep_hue=True
    )


DISTRACTORS = (
    _distractor(0, (0.05, 0.05, 0.09), 0.06, (0.10, 0.68, 0.75), shape="cylinder"),
    _distractor(1, (0.09, 0.045, 0.035), 0.05, (0.92, 0.90, 0.84)),
    _distractor(2, (0.04, 0.04, 0.07), 0.05, (0.55, 0.30, 0.70)),
)
"""The distractors in the order they are added (teal can, white block, purple block); sizes [m], masses [kg]."""
CONTACTS_EACH = 6
"""Contacts one distractor may hold at once (a box on the table has 4; one more touch each side) [contacts]."""
DEFAULT_ROWS = 64
"""Newton's MuJoCo constraint-row capacity per world when a task sets none (``PhysicsCfg.constraints_per_world``)."""


def with_distractors(cfg: TaskCfg, count: int) -> TaskCfg:
    """``cfg`` with the first ``count`` of ``DISTRACTORS`` and their reset events (``count`` 0: ``cfg`` itself).
    One-line errors: a count out of range, a task without a static ``table`` entity."""
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= len(DISTRACTORS):
        raise ValueError(f"distractors must be a whole number from 0 to {len(DISTRACTORS)}, got {count!r}")
    if count == 0:
        return cfg
    tables = [e for e in cfg.entities if e.name == "table" and not e.dynamic]
    if not tables:
        raise ValueError(f"{cfg.task_id or 'this task'} has no static 'table' entity to put distractors on")
    added = [
        dataclasses.replace(d, pos=(PARK_POS[0] + 0.3 * i, PARK_POS[1], 0.5 * d.size[2]))
        for i, d in enumerate(DISTRACTORS[:count])
    ]
    entities = [*cfg.entities, *added]
    events = dict(cfg.events)
    for d in added:
        events[f"place_{d.name}"] = TermCfg(
            func=scatter_on, params={"entity": d.name, "surface": "table", "count": len(entities)}
        )
    return dataclasses.replace(cfg, entities=entities, events=events, physics=_room_for(cfg.physics, count))


def _room_for(physics: PhysicsCfg, count: int) -> PhysicsCfg:
    """``physics`` with MuJoCo's per-world capacities grown by what ``count`` objects standing on the table add:
    ``CONTACTS_EACH`` contacts each, up to 4 constraint rows a contact (a pyramidal cone of 3 dimensions)."""
    contacts = None if physics.contacts_per_world is None else physics.contacts_per_world + CONTACTS_EACH * count
    rows = (physics.constraints_per_world or DEFAULT_ROWS) + 4 * CONTACTS_EACH * count
    return dataclasses.replace(physics, contacts_per_world=contacts, constraints_per_world=rows)


def distractor_count(cfg: TaskCfg) -> int:
    """How many of ``DISTRACTORS`` ``cfg`` holds."""
    names = {d.name for d in DISTRACTORS}
    return sum(e.name in names for e in cfg.entities)
