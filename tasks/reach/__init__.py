"""GalbotG1-Reach-v0: bring the left TCP to a commanded position."""

from pathlib import Path

from newton_lab.task_api.experts import yaml_plan
from newton_lab.task_api.registry import TaskSpec, register

from .config.g1.env_cfg import reach_cfg

SPEC = register(
    TaskSpec(
        id="GalbotG1-Reach-v0",
        cfg=reach_cfg,
        expert=yaml_plan(Path(__file__).parent / "config" / "g1" / "motion_plan.yaml"),
        description="Left TCP to a commanded position (success within 2 cm).",
    )
)
