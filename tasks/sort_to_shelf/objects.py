"""The four sorting objects (as on the reference platform) and everything that depends on which one is sorted.

Positions are env frame [m]; the shelf has a 2 x 2 grid of cells (a = upper row, b = lower row; 1 = left,
2 = right seen from the robot). Place-approach arm postures are re-derived by IK for the authored arm:
TCP at the cell's approach point, pointing into the shelf, from the nav goal (legs lifted for row a).
"""

from __future__ import annotations

from dataclasses import dataclass

from newton_lab.tasks.common.config.g1.postures import UPPER_ROW_LEGS

SHELF_NAV_YAW = -1.5707963267948966
"""The base faces the shelf (-y) when placing [rad]."""
GRASP_Z_OFFSET = 0.025
"""The hand grips this far above the object's centre [m]."""
RELEASE_CLEARANCE = 0.01
"""The object is let go this far above its resting height [m]."""


@dataclass(frozen=True, kw_only=True)
class SortingObject:
    """One sorting object and everything that depends on it."""

    name: str
    """Scene object name (and the ``sorting_object`` option value)."""
    shape: str
    """``box`` or ``cylinder``."""
    size: tuple[float, float, float]
    """Full extents (x, y, z); cylinders: diameter, diameter, height [m]."""
    pos: tuple[float, float, float]
    """Initial position (slot) on the table [m]."""
    color: tuple[float, float, float]
    """RGB in [0, 1]; the colour names the object."""
    cell: str
    """Its shelf cell: ``a1``, ``a2`` (upper row), ``b1``, ``b2``."""
    target: tuple[float, float, float]
    """Object centre when placed [m]."""
    lift_min_z: float
    """Pick success: object centre at or above this [m] (table top + half height + 0.06)."""
    upright_min: float
    """Place success: |object z . world z| at least this (0: no check)."""
    place_base_xy: tuple[float, float]
    """Nav goal / base position while placing [m]."""
    approach_arm: tuple[float, ...]
    """Left-arm posture at the place approach point [rad] (7)."""

    @property
    def upper_row(self) -> bool:
        return self.cell.startswith("a")

    @property
    def legs(self) -> tuple[float, ...]:
        """Leg posture while placing: lifted for the upper row [rad] (5)."""
        return UPPER_ROW_LEGS if self.upper_row else (0.0,) * 5

    @property
    def release_tcp(self) -> tuple[float, float, float]:
        x, y, z = self.target
        return (x, y, z + GRASP_Z_OFFSET + RELEASE_CLEARANCE)


OBJECTS: dict[str, SortingObject] = {
    o.name: o
    for o in (
        SortingObject(
            name="red_cube",
            shape="box",
            size=(0.06, 0.06, 0.07),
            pos=(-0.40, 0.18, 0.36),
            color=(0.85, 0.18, 0.12),
            cell="a1",
            target=(-1.9, -2.1, 0.695),
            lift_min_z=0.42,
            upright_min=0.0,
            place_base_xy=(-1.9, -1.25),
            approach_arm=(1.5348, -0.6566, 0.6701, -2.2628, 0.8934, 0.9588, -0.0131),
        ),
        SortingObject(
            name="blue_cuboid",
            shape="box",
            size=(0.05, 0.05, 0.12),
            pos=(-0.40, 0.06, 0.385),
            color=(0.08, 0.22, 0.85),
            cell="a2",
            target=(-1.5, -2.1, 0.72),
            lift_min_z=0.445,
            upright_min=0.90,
            place_base_xy=(-1.7, -1.25),
            approach_arm=(1.0775, -0.4453, -0.1179, -2.5323, 0.1004, 1.4062, -0.4331),
        ),
        SortingObject(
            name="yellow_cylinder",
            shape="cylinder",
            size=(0.05, 0.05, 0.12),
            pos=(-0.40, -0.06, 0.385),
            color=(0.95, 0.78, 0.08),
            cell="b1",
            target=(-1.9, -2.1, 0.41),
            lift_min_z=0.445,
            upright_min=0.90,
            place_base_xy=(-1.9, -1.25),
            approach_arm=(2.0269, -0.4146, 0.6538, -2.2153, 1.172, 0.4552, 0.4799),
        ),
        SortingObject(
            name="green_cylinder",
            shape="cylinder",
            size=(0.06, 0.06, 0.08),
            pos=(-0.40, -0.18, 0.365),
            color=(0.15, 0.60, 0.22),
            cell="b2",
            target=(-1.5, -2.1, 0.39),
            lift_min_z=0.425,
            upright_min=0.90,
            place_base_xy=(-1.7, -1.25),
            approach_arm=(1.9899, 0.0563, 0.0687, -2.431, 0.1988, 0.4478, 0.203),
        ),
    )
}
DEFAULT_OBJECT = "red_cube"


def sorting_object(name: str | None) -> SortingObject:
    """The object called ``name`` (default red_cube); unknown names fail with the valid ones."""
    name = DEFAULT_OBJECT if name is None else name
    if name not in OBJECTS:
        raise ValueError(f"unknown sorting_object {name!r}; valid values: {list(OBJECTS)}")
    return OBJECTS[name]
