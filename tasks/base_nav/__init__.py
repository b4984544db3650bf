"""GalbotG1-BaseNav-v0: drive the wheeled base to a goal 2 m ahead."""

from newton_lab.registry import register

from .config.g1.env_cfg import base_nav_cfg

register(
    "GalbotG1-BaseNav-v0",
    cfg=base_nav_cfg,
    nav_agent="newton_lab.tasks.base_nav.config.g1.env_cfg:nav_agent",
    description="Drive the mobile base from (0, 0) to (2, 0) (success within 15 cm).",
)
