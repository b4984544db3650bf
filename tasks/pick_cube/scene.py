"""PickCube scene: table, red cube (dynamic), blue block (static container)."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg, SceneCfg

from ..common.table_top import cube, table

CUBE_INIT = (-0.30, 0.18, 0.125)
"""Cube centre at reset (resting on the table top) [m]."""
BLUE_BLOCK_POS = (-0.30, -0.08, 0.11)
"""Blue block centre [m]."""

SCENE = SceneCfg(
    table(),
    cube("cube", CUBE_INIT, (0.85, 0.18, 0.12)),
    EntityCfg(name="blue_block", size=(0.15, 0.15, 0.02), pos=BLUE_BLOCK_POS, dynamic=False, color=(0.08, 0.22, 0.85)),
)
