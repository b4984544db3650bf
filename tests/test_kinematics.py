"""Batched TCP IK: a subset of rows is solved by a smaller power-of-two solver with the same answer per row, the
captured solve equals the eager one, the solutions reach their targets, and the arm-chain model the solves run on
gives the whole robot's TCP."""

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


def test_planner_refines_only_the_rows_left_off(kin, monkeypatch):
    """The expert's IK: ``ik_iterations`` (16) LM steps for every row, ``refine_iterations`` (32) more only for rows
    still off by over 1 mm; reachable rows come out as a 48-step solve's, an unreachable one ends no worse."""
    from newton_lab.agents.planner.agent import PlannerAgent
    from newton_lab.task_api.motion_plan import MotionPlan

    q, pos, quat = _problems(kin, 4)
    pos[3] += 0.3  # out of the arm's reach: 87 mm short after any number of steps
    full = kin.solve(q, pos, quat, iterations=48)
    agent = PlannerAgent(MotionPlan(steps=()))
    agent._kin = kin
    calls = []
    solve = kin.solve
    monkeypatch.setattr(kin, "solve", lambda q, *a, **k: calls.append((len(q), k["iterations"])) or solve(q, *a, **k))
    out, err = agent._solve(q, np.arange(4), pos, quat)
    assert calls == [(4, 16), (1, 32)]
    np.testing.assert_allclose(out[:3], full[:3], atol=1e-4)
    full_err = np.linalg.norm(kin.tcp_poses(full)[:, :3] - pos, axis=1)
    assert err[:3].max() < 1e-3 and 0.05 < err[3] <= full_err[3] + 1e-4


def test_the_chain_model_gives_the_whole_robots_tcp_and_keeps_every_other_coordinate(kin):
    """IK and FK run on the G1 with every joint off the left TCP's chain welded: the TCP equals the whole robot's
    forward kinematics for any value of those joints, and a solve hands back every coordinate it did not solve."""
    import newton
    import warp as wp

    from newton_lab.robots.g1.kinematics import _robot_builder, chain_joints

    rng = np.random.default_rng(1)
    q, pos, quat = _problems(kin, 4)
    off_chain = [c for c in range(kin.robot_coords) if c not in set(kin._chain)]
    assert len(kin._chain) == len(chain_joints("left")) == 15 and len(off_chain) == kin.robot_coords - 15
    q[:, off_chain] = rng.uniform(-0.5, 0.5, size=(4, len(off_chain)))  # head, right arm, grippers, wheels
    q[:, kin._chain[:8]] += rng.uniform(-0.2, 0.2, size=(4, 8))  # base pose and legs
    b, joints = _robot_builder()
    whole = b.finalize(device="cpu")
    state = whole.state()
    link = joints.body[spec.END_EFFECTOR_LINK["left"]]
    for row in range(4):
        state.joint_q.assign(q[row].astype(np.float32))
        newton.eval_fk(whole, state.joint_q, state.joint_qd, state)
        body = state.body_q.numpy()[link]
        tcp = kin.tcp_poses(q[row : row + 1])[0]
        expected = body[:3] + wp.quat_rotate(wp.quat(*body[3:]), wp.vec3(*spec.TCP_OFFSET_POS))
        np.testing.assert_allclose(tcp[:3], np.asarray(expected), atol=1e-5)
    solved = kin.solve(q, pos, quat, iterations=16)
    np.testing.assert_array_equal(solved[:, off_chain], q[:, off_chain].astype(np.float32))
    np.testing.assert_array_equal(solved[:, kin._chain[:8]], q[:, kin._chain[:8]].astype(np.float32))
