"""GalbotG1-Reach-v0: bring the left TCP to a commanded position."""

from newton_lab.registry import register

from .config.g1.env_cfg import reach_cfg

register(
    "GalbotG1-Reach-v0",
    cfg=reach_cfg,
    motion_plan="newton_lab.tasks.reach.config.g1:motion_plan.yaml",
    description="Left TCP to a commanded position (success within 2 cm).",
)
