"""Flat per-step simulator state (robomimic's ``states``) and its named views.

A collected demo stores ``states`` as one (T, D) float32 array per step, ``D = joint_q + joint_qd`` of the
row (every generalized coordinate [m, rad, quaternion] then every velocity [m/s, rad/s]), as robomimic
stores MuJoCo's flattened sim state. ``env_args["newton_lab"]["state_layout"]`` names the column ranges
(``"joint_q"``, ``"articulation/robot/joint_position"``, ``"rigid_object/<name>/root_pose"``, ...).
:func:`state_tree` turns the flat array back into the nested dict older datasets (format 1) stored.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def state_layout(
    coords: int, dofs: int, robot_coords: int, robot_dofs: int, objects: Mapping[str, tuple[int, int]]
) -> dict[str, list[int]]:
    """Column ranges ``[start, stop)`` of the flat state of a row with ``coords`` joint coordinates and
    ``dofs`` joint velocities; ``objects`` maps a free-floating object to its (first coord, first dof)."""
    out = {
        "joint_q": [0, coords],
        "joint_qd": [coords, coords + dofs],
        "articulation/robot/joint_position": [0, robot_coords],
        "articulation/robot/joint_velocity": [coords, coords + robot_dofs],
    }
    for name, (c, d) in objects.items():
        out[f"rigid_object/{name}/root_pose"] = [c, c + 7]  # position [m] + quaternion (x, y, z, w)
        out[f"rigid_object/{name}/root_velocity"] = [coords + d, coords + d + 6]
    return out


def state_tree(states: Any, env_args: Mapping[str, Any]) -> dict[str, Any]:
    """Nested named views of a demo's ``states`` (or ``initial_state``): ``{"articulation": {"robot":
    {"joint_position", "joint_velocity"}}, "rigid_object": {<name>: {"root_pose", "root_velocity"}},
    "joint_q", "joint_qd"}``. A nested dict (datasets of format 1) is returned as it is."""
    if isinstance(states, Mapping):
        return dict(states)
    arr = np.asarray(states)
    layout = (env_args.get("newton_lab") or {}).get("state_layout")
    if not isinstance(layout, Mapping):
        raise ValueError(
            "the dataset's env_args has no newton_lab.state_layout to name its flat states; "
            "re-collect it with this newton_lab"
        )
    if arr.ndim != 2:
        raise ValueError(f"flat states must be (T, D), got shape {arr.shape}")
    tree: dict[str, Any] = {"rigid_object": {}}
    for key, (lo, hi) in layout.items():
        if hi > arr.shape[1]:
            raise ValueError(f"state_layout {key!r} [{lo}, {hi}) exceeds the {arr.shape[1]} state columns")
        node, parts = tree, key.split("/")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = arr[:, lo:hi]
    return tree
