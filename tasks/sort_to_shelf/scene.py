"""SortToShelf world (as on the reference platform): the table with four objects, a 2 x 2 shelf 2.2 m to the
robot's right."""

from __future__ import annotations

from newton_lab.task_api.cfg import EntityCfg, SceneCfg

from .objects import OBJECTS

ROBOT_ROOT = (-1.2, 0.0, 0.0)
"""Robot root at reset [m]."""
_PANEL = (0.10, 0.25, 0.60)
_DIVIDER = (0.12, 0.30, 0.68)


def _board(cell: str, x: float, z: float, color) -> EntityCfg:
    # boards are the object's colour lightened 35 % toward white
    light = tuple(round(c + 0.35 * (1.0 - c), 4) for c in color)
    return EntityCfg(
        name=f"shelf_{cell}_place_board", size=(0.30, 0.30, 0.005), pos=(x, -2.2, z), dynamic=False, color=light
    )


def _entities() -> list[EntityCfg]:
    items = [
        EntityCfg(name="table", size=(0.8, 0.9, 0.50), pos=(-0.30, 0.0, 0.075), dynamic=False, color=(0.42, 0.44, 0.40))
    ]
    for o in OBJECTS.values():
        items.append(
            EntityCfg(name=o.name, shape=o.shape, size=o.size, pos=o.pos, mass=0.05, color=o.color, keep_hue=True)
        )
    items += [
        EntityCfg(
            name="shelf_deck", size=(0.80, 0.40, 0.02), pos=(-1.7, -2.2, 0.335), dynamic=False, color=(0.08, 0.22, 0.85)
        ),
        EntityCfg(
            name="shelf_back_baffle", size=(0.80, 0.02, 0.945), pos=(-1.7, -2.39, 0.4725), dynamic=False, color=_PANEL
        ),
        EntityCfg(
            name="shelf_left_baffle", size=(0.02, 0.40, 0.945), pos=(-2.09, -2.2, 0.4725), dynamic=False, color=_PANEL
        ),
        EntityCfg(
            name="shelf_right_baffle", size=(0.02, 0.40, 0.945), pos=(-1.31, -2.2, 0.4725), dynamic=False, color=_PANEL
        ),
        EntityCfg(
            name="shelf_center_divider",
            size=(0.02, 0.40, 0.945),
            pos=(-1.7, -2.2, 0.4725),
            dynamic=False,
            color=_DIVIDER,
        ),
        EntityCfg(
            name="shelf_cross_divider", size=(0.80, 0.40, 0.02), pos=(-1.7, -2.2, 0.645), dynamic=False, color=_DIVIDER
        ),
    ]
    by_cell = {o.cell: o for o in OBJECTS.values()}
    for cell, x, z in (("a1", -1.9, 0.6575), ("a2", -1.5, 0.6575), ("b1", -1.9, 0.3475), ("b2", -1.5, 0.3475)):
        items.append(_board(cell, x, z, by_cell[cell].color))
    return items


SCENE = SceneCfg(*_entities())
