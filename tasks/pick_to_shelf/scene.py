"""PickToShelf world (as on the reference platform), shared by the Pick / Nav / Place components and the coherent task:
a 0.5 m high table with a 5 x 5 x 16 cm bar, and a one-cell shelf 2 m to the robot's right."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg, SceneCfg

TABLE_TOP_Z = 0.325
"""Table top height [m]."""
BAR_SIZE = (0.05, 0.05, 0.16)
"""The bar's full extents [m] (the reference calls it ``cube``)."""
BAR_POS = (-0.40, 0.18, 0.405)
"""Bar centre at reset, standing on the table [m]."""
DECK_POS = (-1.7, -2.0, 0.34)
DECK_SIZE = (0.50, 0.40, 0.03)
ROBOT_ROOT = (-1.2, 0.0, 0.0)
"""Robot root at reset [m]."""

SHELF_COLOR = (0.10, 0.25, 0.60)


SCENE = SceneCfg(
    EntityCfg(name="table", size=(0.8, 0.9, 0.50), pos=(-0.30, 0.0, 0.075), dynamic=False, color=(0.42, 0.44, 0.40)),
    EntityCfg(name="bar", size=BAR_SIZE, pos=BAR_POS, mass=0.05, color=(0.85, 0.18, 0.12)),
    EntityCfg(name="shelf_deck", size=DECK_SIZE, pos=DECK_POS, dynamic=False, color=(0.08, 0.22, 0.85)),
    EntityCfg(
        name="shelf_back_baffle", size=(0.50, 0.06, 0.595), pos=(-1.7, -2.17, 0.2975), dynamic=False, color=SHELF_COLOR
    ),
    EntityCfg(
        name="shelf_left_baffle", size=(0.06, 0.40, 0.595), pos=(-1.92, -2.0, 0.2975), dynamic=False, color=SHELF_COLOR
    ),
    EntityCfg(
        name="shelf_right_baffle", size=(0.06, 0.40, 0.595), pos=(-1.48, -2.0, 0.2975), dynamic=False, color=SHELF_COLOR
    ),
)
