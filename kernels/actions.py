"""Action packing: one kernel maps the (num_envs, action_dim) action tensor onto drive targets."""

from __future__ import annotations

import warp as wp

TARGET_POSITION = 0
"""Column writes an absolute position target (coordinate index)."""
TARGET_VELOCITY = 1
"""Column writes a velocity target (DOF index)."""


@wp.kernel
def apply_actions(
    actions: wp.array2d(dtype=float),
    kind: wp.array(dtype=int),
    index: wp.array(dtype=int),
    low: wp.array(dtype=float),
    high: wp.array(dtype=float),
    coords_per_world: int,
    dofs_per_world: int,
    target_q: wp.array(dtype=float),
    target_qd: wp.array(dtype=float),
):
    """Write column ``c`` of row ``w`` (clipped to [low, high]) to its joint's drive target."""
    w, c = wp.tid()
    a = wp.clamp(actions[w, c], low[c], high[c])
    if kind[c] == TARGET_POSITION:
        target_q[w * coords_per_world + index[c]] = a
    else:
        target_qd[w * dofs_per_world + index[c]] = a
