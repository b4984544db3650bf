"""Reach scene: the table only (slot 0)."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg

from ..common.table_top import table

TABLE = 0


def entities() -> list[EntityCfg]:
    return [table()]
