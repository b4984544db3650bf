"""PushCube scene: the table and one dynamic cube (the goal region is a commanded point, not an object)."""

from __future__ import annotations

from newton_lab.task_api.cfg import SceneCfg

from ..common.table_top import cube, table

CUBE_INIT = (-0.36, 0.17, 0.125)
"""Cube centre at reset, resting on the table [m]."""

SCENE = SceneCfg(table(), cube("cube", CUBE_INIT, (0.85, 0.18, 0.12)))
