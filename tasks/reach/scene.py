"""Reach scene: the table only (slot 0)."""

from __future__ import annotations

from newton_lab.envs.cfg import EntityCfg

from ..common.table_top import table

TABLE = 0


def entities() -> list[EntityCfg]:
    return [table()]
