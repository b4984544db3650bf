"""Reach scene: the table only."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg, SceneCfg

from ..common.table_top import table

SCENE = SceneCfg(table())


def entities() -> list[EntityCfg]:
    return SCENE.entities
