"""The reference table-top scene pieces (env frame, [m], [kg]); any robot can stand at this table."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg

TABLE_TOP_Z = 0.10
CUBE_SIZE = 0.05
CUBE_MASS = 0.04


def table() -> EntityCfg:
    """0.8 x 1.0 x 0.05 static table, top at z = 0.10."""
    return EntityCfg(
        name="table", size=(0.8, 1.0, 0.05), pos=(-0.30, 0.0, 0.075), dynamic=False, color=(0.42, 0.44, 0.40)
    )


def cube(name: str, pos, color) -> EntityCfg:
    """A 5 cm, 40 g dynamic cube."""
    return EntityCfg(name=name, size=(CUBE_SIZE,) * 3, pos=pos, mass=CUBE_MASS, color=color)
