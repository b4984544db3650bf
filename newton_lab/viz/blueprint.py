"""The default rerun layout of a newton_lab recording: a large 3D view of the scene looking at row 0, the
per-row scalars (one time-series tab per row) and the episode events in a narrower column."""

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
    return rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=target + EYE_DISTANCE * direction,
                             look_target=target, eye_up=[0.0, 0.0, 1.0])


def default_blueprint(rows: int, *, eye: rrb.EyeControls3D | None = None, hidden=()) -> rrb.Blueprint:
    """The layout: 3D ``world`` view (3/4 of the width, ``hidden`` entity paths switched off), then per-row
    ``metrics/<row>`` plots as tabs over the ``events`` log."""
    scene = rrb.Spatial3DView(origin="world", name="scene", eye_controls=eye,
                              overrides={path: rrb.EntityBehavior(visible=False) for path in hidden})
    plots = rrb.Tabs(*(rrb.TimeSeriesView(origin=f"metrics/{w}", name=f"row {w}") for w in range(rows)),
                     name="scalars per row")
    side = rrb.Vertical(plots, rrb.TextLogView(origin="events", name="episode events"), row_shares=[2, 1])
    return rrb.Blueprint(rrb.Horizontal(scene, side, column_shares=[3, 1]),
                         rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
                         rrb.TimePanel(state="collapsed"))
