"""LiftCube scene: the table and one dynamic cube."""

from __future__ import annotations

from newton_lab.task_api.cfg import SceneCfg

from ..common.table_top import cube, table

CUBE_INIT = (-0.30, 0.18, 0.125)
"""Cube centre at reset (resting on the table top, z = 0.10 + 0.025) [m]."""

SCENE = SceneCfg(table(), cube("cube", CUBE_INIT, (0.85, 0.18, 0.12)))
