"""Planner trajectory gather: joint-space waypoints in device buffers -> per-row action rows."""

from __future__ import annotations

import warp as wp


@wp.kernel
def gather_plan_actions(
    waypoints: wp.array3d(dtype=float),
    start_q: wp.array2d(dtype=float),
    seg_start: wp.array2d(dtype=int),
    seg_interp: wp.array2d(dtype=int),
    seg_settle_at: wp.array2d(dtype=int),
    num_segments: wp.array(dtype=int),
    plan_end: wp.array(dtype=int),
    cursor: wp.array(dtype=int),
    joint_q: wp.array2d(dtype=float),
    arm_coords: wp.array(dtype=int),
    settle_tol: float,
    arm_cols: wp.array(dtype=int),
    gripper_col: int,
    actions: wp.array2d(dtype=float),
):
    """Write row ``w``'s commanded arm joints and gripper at its cursor, then advance the cursor.

    The arm has ``A = arm_cols.shape[0]`` joints (its binding's). Segment ``k`` starts at frame
    ``seg_start[w, k]``, moves linearly from the previous waypoint (or ``start_q`` for ``k = 0``) to
    ``waypoints[w, k, :A]`` over ``seg_interp[w, k]`` frames, then holds; ``waypoints[w, k, A]`` is the gripper
    command for the whole segment (written when ``gripper_col >= 0``). Past the end the last waypoint is held. From
    frame ``seg_settle_at[w, k]`` (-1: never) a segment settles: once the arm's joints (``joint_q[w, arm_coords]``) are
    all within ``settle_tol`` [rad] of the waypoint, the cursor skips to the next segment (or, after the last, to
    ``plan_end[w]``).
    """
    w = wp.tid()
    arm = arm_cols.shape[0]
    t = cursor[w]
    n = num_segments[w]
    if n == 0:
        return
    k = int(0)
    for s in range(n):
        if seg_start[w, s] <= t:
            k = s
    settle_at = seg_settle_at[w, k]
    if settle_at >= 0 and t >= settle_at:
        err = float(0.0)
        for j in range(arm):
            err = wp.max(err, wp.abs(joint_q[w, arm_coords[j]] - waypoints[w, k, j]))
        if err <= settle_tol:
            if k + 1 < n:
                k = k + 1
                t = seg_start[w, k]
            else:
                t = wp.max(t, plan_end[w])
    alpha = float(1.0)
    m = seg_interp[w, k]
    if m > 0:
        alpha = wp.min(1.0, float(t - seg_start[w, k] + 1) / float(m))
    for j in range(arm):
        a = start_q[w, j]
        if k > 0:
            a = waypoints[w, k - 1, j]
        actions[w, arm_cols[j]] = a + alpha * (waypoints[w, k, j] - a)
    if gripper_col >= 0:
        actions[w, gripper_col] = waypoints[w, k, arm]
    cursor[w] = t + 1
