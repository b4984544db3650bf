"""The default rerun layout of a newton_lab recording: a large 3D view of the scene looking at row 0, a 2D panel
per camera of row 0 (one tab per image stream: RGB, depth, segmentation), the per-row scalars (one time-series
tab per row) and the episode events in a narrower column."""

from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb

EYE_DISTANCE = 2.6
"""Distance [m] of the default 3D eye from the point it looks at."""


def eye_for(robot_xyz, scene_xyz) -> rrb.EyeControls3D:
    """An orbital eye looking at the middle of the robot and its task objects (world frame of row 0 [m]):
    from the objects' side, 40 degrees off the robot-to-objects axis, 30 degrees above."""
    robot, scene = np.asarray(robot_xyz, dtype=float), np.asarray(scene_xyz, dtype=float)
    axis = (scene - robot)[:2]
    axis = axis / np.linalg.norm(axis) if np.linalg.norm(axis) > 1e-6 else np.array([1.0, 0.0])
    yaw = np.arctan2(axis[1], axis[0]) + np.deg2rad(40.0)
    pitch = np.deg2rad(30.0)
    target = np.array([*(0.5 * (robot[:2] + scene[:2])), 0.6])
    direction = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital,
        position=target + EYE_DISTANCE * direction,
        look_target=target,
        eye_up=[0.0, 0.0, 1.0],
    )


def camera_panel(camera: str, data) -> rrb.Tabs:
    """Row 0's ``camera``: one 2D view per image stream of ``data`` (in the camera's image space)."""
    origin = f"world/0/cameras/{camera}"
    return rrb.Tabs(
        *(rrb.Spatial2DView(origin=origin, contents=f"$origin/{d}", name=f"{camera} {d}") for d in data), name=camera
    )


def default_blueprint(
    rows: int, *, eye: rrb.EyeControls3D | None = None, hidden=(), cameras: dict | None = None
) -> rrb.Blueprint:
    """The layout: 3D ``world`` view (``hidden`` entity paths switched off), a column of camera panels
    (``cameras``: {camera: image data}, none without), then per-row ``metrics/<row>`` plots as tabs over the
    ``events`` log."""
    scene = rrb.Spatial3DView(
        origin="world",
        name="scene",
        eye_controls=eye,
        overrides={path: rrb.EntityBehavior(visible=False) for path in hidden},
    )
    plots = rrb.Tabs(
        *(rrb.TimeSeriesView(origin=f"metrics/{w}", name=f"row {w}") for w in range(rows)), name="scalars per row"
    )
    side = rrb.Vertical(plots, rrb.TextLogView(origin="events", name="episode events"), row_shares=[2, 1])
    columns, shares = [scene, side], [3, 1]
    if cameras:
        columns, shares = [scene, rrb.Vertical(*(camera_panel(c, d) for c, d in cameras.items())), side], [3, 2, 1]
    return rrb.Blueprint(
        rrb.Horizontal(*columns, column_shares=shares),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )
