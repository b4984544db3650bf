"""PolicyAgent: per-row observation history, re-planning every action horizon, checkpoint checks."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from newton_lab.policies.agent import PolicyAgent


class RecordingPolicy:
    """A stand-in policy (the env is real): returns the current target plus the row's step marker and
    records every history it is given."""

    def __init__(self, env, obs_keys):
        self.cfg = SimpleNamespace(obs_horizon=2, action_horizon=3)
        self.obs_keys = obs_keys
        self.info = {
            "task_id": env.task_id,
            "action_joint_names": list(env.action_joint_names),
            "obs_dims": {k: env.task.obs_terms[k].stop - env.task.obs_terms[k].start for k in obs_keys},
        }
        self.calls = []
        self.env = env

    def predict_action(self, history, generator=None):
        self.calls.append(history.clone())
        base = self.env.current_action()[: history.shape[0]]
        return base.unsqueeze(1).repeat(1, self.cfg.action_horizon, 1)


def test_history_is_per_row(reach_env):
    env = reach_env
    env.reset()
    policy = RecordingPolicy(env, ["pose_command"])
    agent = PolicyAgent(policy)
    agent.act(env)  # first call: both rows plan with their first obs repeated
    assert len(policy.calls) == 1 and policy.calls[0].shape == (2, 2, 3)
    torch.testing.assert_close(policy.calls[0][:, 0], policy.calls[0][:, 1])
    for _ in range(2):
        env.step(agent.act(env))
    assert len(policy.calls) == 1  # queue of 3 actions not yet used up
    env.step(agent.act(env))  # 4th act re-plans both rows
    assert len(policy.calls) == 2
    env.reset([1])  # only row 1 starts over: new goal, refilled history, immediate re-plan
    agent.act(env)
    assert len(policy.calls) == 3 and policy.calls[-1].shape[0] == 1
    goal = env.obs[1, env.task.obs_terms["pose_command"]]
    torch.testing.assert_close(policy.calls[-1][0], goal.expand(2, 3))


def test_checkpoint_mismatches_are_one_line_errors(reach_env, pick_env, tmp_path):
    policy = RecordingPolicy(pick_env, ["cube_pose"])
    with pytest.raises(ValueError) as e:
        PolicyAgent(policy).act(reach_env)
    assert "GalbotG1-PickCube-v0" in str(e.value) and "\n" not in str(e.value)
    policy = RecordingPolicy(reach_env, ["pose_command"])
    policy.obs_keys = ["no_such_term"]
    with pytest.raises(ValueError) as e:
        PolicyAgent(policy).act(reach_env)
    assert "no_such_term" in str(e.value)
    with pytest.raises(FileNotFoundError):
        PolicyAgent.from_checkpoint(tmp_path / "missing.pt")
