"""PickToShelf: pick a bar from the table, drive to the shelf, place it (components + coherent task)."""

from newton_lab.registry import register

from .config.g1.env_cfg import coherent_cfg, nav_cfg, pick_cfg, place_cfg

_PLANS = "newton_lab.tasks.pick_to_shelf.config.g1"

register("GalbotG1-PickToShelf-Pick-v0", cfg=pick_cfg, motion_plan=f"{_PLANS}:pick_plan.yaml",
         description="Pick the bar from the table into the carry posture.")
register("GalbotG1-PickToShelf-Nav-v0", cfg=nav_cfg, nav_agent=f"{_PLANS}.env_cfg:nav_agent",
         description="Carry the bar to the shelf on the wheeled base.")
register("GalbotG1-PickToShelf-Place-v0", cfg=place_cfg, motion_plan=f"{_PLANS}:place_plan.yaml",
         description="Place the carried bar upright on the shelf deck.")
register("GalbotG1-PickToShelf-v0", cfg=coherent_cfg, task_flow=True,
         description="Pick -> nav -> place in one episode (coherent task).")
