"""Divergence guard on real physics: a row driven to NaN ends with reason ``diverged`` inside the fused task
kernel, resets alone into a finite episode, leaves the other rows bitwise unchanged, and never reaches a dataset."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
import warp as wp
from newton_lab.kernels import fuse

from newton_lab.agents import ZeroAgent
from newton_lab.datasets import list_demos, read_episode
from newton_lab.envs import rollout
from newton_lab.envs.launches import build_task_kernels
from newton_lab.task_api.cfg import BUILTIN_TERMINATION_REASONS, DIVERGED

FAULT = 1e30
"""Finite, so ``check_actions`` lets it through; the arm's drive target becomes absurd and the row goes NaN."""


def test_reason_codes_match_their_names(pick_env):
    names = pick_env.task.termination_reasons
    assert names[: len(BUILTIN_TERMINATION_REASONS)] == list(BUILTIN_TERMINATION_REASONS)
    assert names[fuse.REASON_SUCCESS] == "success" and names[fuse.REASON_TIME_OUT] == "time_out"
    assert names[fuse.REASON_DIVERGED] == DIVERGED and fuse.FIRST_FAILURE_REASON == len(BUILTIN_TERMINATION_REASONS)
    assert names[fuse.FIRST_FAILURE_REASON :] == list(pick_env.cfg.terminations)
    assert pick_env.cfg.divergence_bounds == (50.0, 100.0, 1000.0)
    term = next(iter(pick_env.cfg.terminations.values()))
    cfg = dataclasses.replace(pick_env.cfg, terminations={DIVERGED: term})
    with pytest.raises(ValueError, match="may not be named"):
        build_task_kernels(cfg, pick_env.task.obs_terms)


def _run(env, steps: int, fault_step: int | None, fault_row: int = 1):
    """Reset every row with fresh episode counters (same seeded draws) and step a fixed action sequence; the
    fault row gets ``FAULT`` in its first column at ``fault_step``. Returns the per-step history."""
    env.buffers.episode_count.zero_()
    env.reset()
    base = env.current_action().clone()
    hist = {k: [] for k in ("obs", "q", "qd", "body_q", "reward", "reason", "count")}
    for t in range(steps):
        a = base.clone()
        a[:, 0] += 0.02 * t  # swing the shoulder: the healthy rows move
        if t == fault_step:
            a[fault_row, 0] = FAULT
        obs, reward, _, _, info = env.step(a)
        n = env.num_envs
        hist["obs"].append(obs.clone())
        hist["q"].append(wp.to_torch(env.state.joint_q).view(n, -1).clone())
        hist["qd"].append(wp.to_torch(env.state.joint_qd).view(n, -1).clone())
        hist["body_q"].append(wp.to_torch(env.state.body_q).view(n, -1).clone())
        hist["reward"].append(reward.clone())
        hist["reason"].append(info["termination_reason"].clone())
        hist["count"].append(env.buffers.episode_count.clone())
    return {k: torch.stack(v) for k, v in hist.items()}


def test_faulty_row_diverges_resets_alone_and_others_are_bitwise_unchanged(pick_env):
    env, fault_step, steps = pick_env, 2, 14
    clean = _run(env, steps, None)
    faulty = _run(env, steps, fault_step)
    # the faulty row reports `diverged` within a few steps, and once
    reasons = [env.task.termination_reasons[int(r)] for r in faulty["reason"][:, 1]]
    hit = reasons.index(DIVERGED)
    assert fault_step <= hit <= fault_step + 3 and reasons.count(DIVERGED) == 1
    assert DIVERGED not in [env.task.termination_reasons[int(r)] for r in clean["reason"].flatten()]
    assert int(faulty["count"][hit, 1]) == int(faulty["count"][hit - 1, 1]) + 1  # it reset in that step
    assert float(faulty["reward"][hit, 1]) == 0.0
    # from the reset on, its new episode is finite: observation, state and the solver's data of its world
    for key in ("obs", "q", "qd", "body_q"):
        assert torch.isfinite(faulty[key][hit:, 1]).all(), key
    data = env.solver.mjw_data
    for name in ("qpos", "qvel", "qacc", "qacc_warmstart", "qfrc_constraint"):
        assert np.isfinite(getattr(data, name).numpy()[1]).all(), name
    assert int(faulty["count"][-1, 1]) == int(faulty["count"][hit, 1])  # no second divergence
    # the other row never noticed: bitwise the run without the fault
    for key in clean:
        assert torch.equal(clean[key][:, 0], faulty[key][:, 0]), key
    # and the guard does not fire on healthy motion
    assert torch.isfinite(clean["obs"]).all() and (clean["count"] == clean["count"][0]).all()


class FaultyAgent(ZeroAgent):
    """Holds every joint, but sends ``FAULT`` to ``row`` on its ``at``-th call."""

    def __init__(self, row: int = 1, at: int = 2):
        self.row, self.at, self.calls = row, at, 0

    def act(self, env, env_ids=None) -> torch.Tensor:
        a = super().act(env).clone()
        if self.calls == self.at:
            a[self.row, 0] = FAULT
        self.calls += 1
        return a


def _frames_finite(ep) -> bool:
    return rollout.all_finite({k: v for k, v in ep.items() if k != "attrs"})


def test_collect_drops_and_counts_the_diverged_episode(pick_env, tmp_path):
    path = tmp_path / "faulty.hdf5"
    ref = pick_env.collect(agent=FaultyAgent(), episodes=3, path=path, max_steps=6, progress=False)
    assert ref["episodes"] == 3 and ref["diverged"] == 1
    assert ref["termination_reasons"][DIVERGED] == 1 and ref["termination_reasons"]["max_steps"] == 2
    ids = list_demos(path)
    assert len(ids) == 2 and ref["saved_demo_ids"] == ids
    for demo in ids:
        ep = read_episode(path, demo)
        assert ep["attrs"]["termination_reason"] != DIVERGED and _frames_finite(ep)
        assert np.abs(ep["actions"]).max() < 1e3


class TeleportingAgent(ZeroAgent):
    """Holds every joint; on its ``at``-th call moves ``row``'s cube 60 m away: finite, only the guard's distance
    bound says the row diverged (the frames hold no NaN for the finiteness check to catch)."""

    def __init__(self, row: int = 1, at: int = 2):
        self.row, self.at, self.calls = row, at, 0

    def act(self, env, env_ids=None) -> torch.Tensor:
        if self.calls == self.at:
            wp.to_torch(env.state.joint_q).view(env.num_envs, -1)[self.row, env.task.entities["cube"].coord] = 60.0
        self.calls += 1
        return super().act(env).clone()


def test_collect_drops_a_finite_diverged_episode(pick_env, tmp_path):
    path = tmp_path / "far.zarr"
    ref = pick_env.collect(agent=TeleportingAgent(), episodes=3, path=path, max_steps=6, progress=False)
    assert ref["diverged"] == 1 and ref["termination_reasons"] == {DIVERGED: 1, "max_steps": 2}
    ids = list_demos(path)
    assert len(ids) == 2 and ref["saved_demo_ids"] == ids
    for demo in ids:
        ep = read_episode(path, demo)
        assert ep["attrs"]["termination_reason"] != DIVERGED and np.abs(ep["obs"]["cube_pose"]).max() < 10


@pytest.mark.parametrize("writer", ["thread", "process"])
def test_collect_skips_an_episode_with_a_non_finite_frame(pick_env, tmp_path, monkeypatch, writer):
    """A non-finite frame the guard did not catch is dropped too, and counted as diverged (the recorded frame
    itself is poisoned: the finiteness check runs on the gathered buffers of all rows that ended together), whoever
    writes the episodes."""
    real = rollout.EpisodeRecorder.fetch

    def poisoned(self, rows, lengths):
        if 0 in list(rows):
            self._frames[0, int(lengths[list(rows).index(0)]) - 1, self.layout.frame["obs/cube_pose"][0]] = float("nan")
        return real(self, rows, lengths)

    monkeypatch.setattr(rollout.EpisodeRecorder, "fetch", poisoned)
    path = tmp_path / "poisoned.zarr"
    ref = pick_env.collect(agent=ZeroAgent(), episodes=2, path=path, max_steps=3, progress=False, writer=writer)
    assert ref["diverged"] == 1 and ref["termination_reasons"] == {DIVERGED: 1, "max_steps": 1}
    ids = list_demos(path)
    assert len(ids) == 1 and _frames_finite(read_episode(path, ids[0]))


def test_evaluate_counts_the_diverged_episode(pick_env):
    summary = pick_env.evaluate(agent=FaultyAgent(row=0, at=1), episodes=2, max_steps=5, progress=False)
    assert summary["diverged"] == 1 and summary["termination_reasons"][DIVERGED] == 1
    assert summary["success_masks"].count(True) == 0 and set(rollout.EVAL_REPORT_KEYS) <= set(summary)


def test_finiteness_is_checked_over_each_episode_steps_only(pick_env):
    """The batched check looks at each row's own steps: a NaN left past a shorter episode's end (a stale step of
    an earlier episode in that row's buffer) does not drop it; one inside an episode does."""
    recorder = rollout.EpisodeRecorder(pick_env, 10)
    col = recorder.layout.frame["obs/cube_pose"][0]
    recorder._frames[0, 3, col] = float("nan")  # row 0 ends after 2 steps: stale
    recorder._frames[1, 1, col] = float("nan")  # row 1 runs 4 steps: inside
    trees, finite = recorder.episodes([0, 1], [2, 4])
    assert finite == {0: True, 1: False}
    assert rollout.all_finite(trees[0]) and not rollout.all_finite(trees[1])  # the per-tree check agrees


def _cube_dof(env) -> int:
    """World-local first velocity coordinate of the cube's free joint (linear [m/s] x, y, z, then angular)."""
    joint = list(env.model.joint_q_start.numpy()).index(env.task.entities["cube"].coord)
    return int(env.model.joint_qd_start.numpy()[joint])


# (cube position (x, y, z) or None to keep it, cube twist or None): finite states past each of the
# cfg's bounds (50 m, 100 m/s, 1000 rad/s) and, beside each, one well inside it. The fast and spinning cubes
# fly 3 m up so no contact tames them; one control step (0.05 s) at 200 m/s moves the cube 10 m, inside 50 m.
BOUNDS_CASES = {
    "teleported to 60 m": ((60.0, 0.18, 0.125), None, True),
    "at 40 m": ((40.0, 0.18, 3.0), None, False),
    "at 200 m/s": ((-0.3, 0.18, 3.0), (0.0, 200.0, 0.0, 0.0, 0.0, 0.0), True),
    "at 90 m/s": ((-0.3, 0.18, 3.0), (0.0, 90.0, 0.0, 0.0, 0.0, 0.0), False),
    "spinning at 2000 rad/s": ((-0.3, 0.18, 3.0), (0.0, 0.0, 0.0, 0.0, 0.0, 2000.0), True),
    "spinning at 900 rad/s": ((-0.3, 0.18, 3.0), (0.0, 0.0, 0.0, 0.0, 0.0, 900.0), False),
}


@pytest.mark.parametrize("case", list(BOUNDS_CASES))
def test_finite_state_beyond_the_bounds_is_diverged(pick_env, case):
    """The guard is more than a NaN check: a finite cube too far, too fast or spinning too fast ends its row with
    ``diverged`` in the very step, the other row does not notice; a cube inside the bounds is left alone."""
    env = pick_env
    pos, twist, diverges = BOUNDS_CASES[case]
    env.buffers.episode_count.zero_()
    env.reset()
    try:
        q = wp.to_torch(env.state.joint_q).view(env.num_envs, -1)
        qd = wp.to_torch(env.state.joint_qd).view(env.num_envs, -1)
        coord, dof = env.task.entities["cube"].coord, _cube_dof(env)
        q[1, coord : coord + 3] = torch.tensor(pos, dtype=q.dtype)
        if twist is not None:
            qd[1, dof : dof + 6] = torch.tensor(twist, dtype=qd.dtype)
        count = env.buffers.episode_count.clone()
        _, _, terminated, _, info = env.step(env.current_action())
        reasons = [env.task.termination_reasons[int(r)] for r in info["termination_reason"]]
        assert reasons[0] == "none" and not bool(terminated[0])
        if diverges:
            assert reasons[1] == DIVERGED and bool(terminated[1])
            assert int(env.buffers.episode_count[1]) == int(count[1]) + 1  # it reset in that step
        else:
            assert reasons[1] == "none" and not bool(terminated[1])
            assert (env.buffers.episode_count == count).all()
    finally:
        env.reset()
