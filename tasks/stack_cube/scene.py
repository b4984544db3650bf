"""StackCube scene: table and three dynamic cubes. Slots index entities."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg

from ..common.table_top import cube, table

TABLE, CUBE_1, CUBE_2, CUBE_3 = 0, 1, 2, 3
CUBE_INITS = ((-0.37, 0.18, 0.125), (-0.30, 0.18, 0.125), (-0.23, 0.18, 0.125))


def entities() -> list[EntityCfg]:
    colors = ((0.85, 0.18, 0.12), (0.95, 0.76, 0.10), (0.12, 0.62, 0.24))
    return [table()] + [cube(f"cube_{i + 1}", CUBE_INITS[i], colors[i]) for i in range(3)]
