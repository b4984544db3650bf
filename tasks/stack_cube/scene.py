"""StackCube scene: table and three dynamic cubes."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg, SceneCfg

from ..common.table_top import cube, table

CUBE_INITS = ((-0.37, 0.18, 0.125), (-0.30, 0.18, 0.125), (-0.23, 0.18, 0.125))


_COLORS = ((0.85, 0.18, 0.12), (0.95, 0.76, 0.10), (0.12, 0.62, 0.24))
SCENE = SceneCfg(table(), *(cube(f"cube_{i + 1}", CUBE_INITS[i], _COLORS[i]) for i in range(3)))
CUBE_1, CUBE_2, CUBE_3 = (SCENE.slot(f"cube_{i}") for i in (1, 2, 3))


def entities() -> list[EntityCfg]:
    return SCENE.entities
