"""GalbotG1-BaseNav-v0: drive the wheeled base to a goal 2 m ahead."""

from newton_lab.task_api.registry import TaskSpec, register

from .config.g1.env_cfg import base_nav_cfg, nav_expert

SPEC = register(
    TaskSpec(
        id="GalbotG1-BaseNav-v0",
        cfg=base_nav_cfg,
        expert=nav_expert,
        description="Drive the mobile base from (0, 0) to (2, 0) (success within 15 cm).",
    )
)
