"""Batched TCP IK: a subset of rows is solved by a smaller power-of-two solver with the same answer per row, the
captured solve equals the eager one, and the solutions reach their targets."""

from __future__ import annotations

import numpy as np
import pytest

from newton_lab.robots.g1 import spec
from newton_lab.robots.g1.kinematics import TcpKinematics


@pytest.fixture(scope="module")
def kin():
    return TcpKinematics(4, device="cpu", arm="left")


def _problems(kin, n):
    rng = np.random.default_rng(0)
    q = np.zeros((n, kin.robot_coords))
    q[:, kin.arm_coords] = [-0.9451, 0.0833, 0.0819, 2.0675, 0.0449, 0.4443, -0.0746]  # PickCube's left arm
    start = kin.tcp_poses(q)
    pos = start[:, :3] + rng.uniform(-0.05, 0.05, size=(n, 3))
    quat = np.tile(np.asarray(spec.TOP_DOWN_TCP_QUAT), (n, 1))
    return q, pos, quat


def test_subset_solves_match_the_full_batch_and_reach_the_targets(kin):
    q, pos, quat = _problems(kin, 4)
    full = kin.solve(q, pos, quat, iterations=48)
    again = kin.solve(q, pos, quat, iterations=48)  # the captured graph (the first call ran eagerly)
    np.testing.assert_allclose(again, full, atol=1e-6)
    for rows in ([2], [0, 3], [1, 2, 3]):  # solver sizes 1, 2 and 4 (padded)
        part = kin.solve(q[rows], pos[rows], quat[rows], iterations=48)
        assert part.shape == (len(rows), kin.robot_coords)
        np.testing.assert_allclose(part, full[rows], atol=1e-4)
    err = np.linalg.norm(kin.tcp_poses(full)[:, :3] - pos, axis=1)
    assert err.max() < 5e-3, err
    with pytest.raises(ValueError, match="IK takes 1..4 problems"):
        kin.solve(np.zeros((5, kin.robot_coords)), np.zeros((5, 3)), np.zeros((5, 4)))
