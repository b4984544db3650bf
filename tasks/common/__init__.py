"""Pieces shared by the G1 table-top tasks: the table, robot postures, action terms, generic terms."""

from __future__ import annotations

import dataclasses


def register_mimic_variant(source_task: str, cfg, mimic) -> str:
    """Register ``<source>-Mimic-v0``: the same scene, terms and randomisation as ``source_task`` (built by
    ``cfg``) plus its Mimic decomposition ``mimic``. Returns the new id."""
    from newton_lab.registry import register

    task_id = source_task.replace("-v0", "-Mimic-v0")

    def mimic_cfg():
        return dataclasses.replace(cfg(), task_id=task_id)

    register(task_id, cfg=mimic_cfg, mimic=mimic, source_task=source_task,
             description=f"Mimic generation variant of {source_task}.")
    return task_id
