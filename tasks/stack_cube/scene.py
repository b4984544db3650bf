"""StackCube scene: table and three dynamic cubes."""

from __future__ import annotations

import dataclasses

from newton_lab.task_api.cfg import SceneCfg

from ..common.table_top import cube, table

CUBES = ("cube_1", "cube_2", "cube_3")
CUBE_INITS = ((-0.37, 0.18, 0.125), (-0.30, 0.18, 0.125), (-0.23, 0.18, 0.125))
"""Cube centres at reset (no randomisation) [m]."""
_COLORS = ((0.85, 0.18, 0.12), (0.95, 0.76, 0.10), (0.12, 0.62, 0.24))
"""Red, yellow, green: the colour names the cube (``keep_hue``), so that a policy from pixels knows which goes where
under vision randomisation."""

SCENE = SceneCfg(
    table(),
    *(
        dataclasses.replace(cube(name, pos, color), keep_hue=True)
        for name, pos, color in zip(CUBES, CUBE_INITS, _COLORS)
    ),
)
