"""SortToShelf: sort one of four objects from the table into its shelf cell (components + coherent task).

Every id takes ``task_options={"sorting_object": "red_cube" | "blue_cuboid" | "yellow_cylinder" |
"green_cylinder"}``.
"""

from newton_lab.registry import register

from .config.g1.env_cfg import coherent_cfg, nav_cfg, pick_cfg, place_cfg

_CFG = "newton_lab.tasks.sort_to_shelf.config.g1.env_cfg"

register("GalbotG1-SortToShelf-Pick-v0", cfg=pick_cfg, motion_plan=f"{_CFG}:pick_plan",
         description="Pick the sorting object from the table into the ready posture.")
register("GalbotG1-SortToShelf-Nav-v0", cfg=nav_cfg, nav_agent=f"{_CFG}:nav_sequence_agent",
         description="Drive to the object's shelf cell, lift the legs for the upper row, arm to place start.")
register("GalbotG1-SortToShelf-Place-v0", cfg=place_cfg, motion_plan=f"{_CFG}:place_plan",
         description="Place the carried object in its shelf cell and retract the arm.")
register("GalbotG1-SortToShelf-v0", cfg=coherent_cfg, task_flow=True,
         description="Pick -> nav -> place of one sorting object in one episode (coherent task).")
