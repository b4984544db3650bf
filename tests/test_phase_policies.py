"""Phase policies composed into a coherent task: each phase's policy writes its own columns, the others hold or
run their expert; a checkpoint for the wrong phase, or one that needs what the env does not give, is refused in
one line; the evaluation summary says where rows stop."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from newton_lab.envs import make_env
from newton_lab.policies.agent import PolicyAgent, compose_phase_policies
from newton_lab.task_api.registry import lookup

COHERENT = "GalbotG1-PickToShelf-v0"
MARK = 0.123
"""What the stand-in policies put in every column they own."""


class ConstantPolicy:
    """A stand-in for a trained component policy (the env is real): ``MARK`` in each of its component's columns."""

    def __init__(self, env, component: str, obs_keys=("robot_joint_pos", "gripper_pos"), images=None):
        names = [j for t in lookup(component).make_cfg().actions for j in env.robot.joint_groups[t.group]]
        self.cfg = SimpleNamespace(obs_horizon=2, action_horizon=4, image_keys=list(images or []))
        self.obs_keys = list(obs_keys)
        self.info = {
            "task_id": component,
            "action_joint_names": names,
            "obs_dims": {
                k: env.task.obs_terms[k].stop - env.task.obs_terms[k].start for k in obs_keys if k in env.task.obs_terms
            },
        }

    def predict_action(self, history, generator=None):
        n = history.shape[0]
        return torch.full((n, self.cfg.action_horizon, len(self.info["action_joint_names"])), MARK)


@pytest.fixture(scope="module")
def coherent_env():
    return make_env(COHERENT, num_envs=2, device="cpu", seed=3, randomize=True, cameras=False)


def test_each_phase_policy_writes_its_own_columns(coherent_env):
    env = coherent_env
    pick = PolicyAgent(ConstantPolicy(env, "GalbotG1-PickToShelf-Pick-v0"))
    agent = compose_phase_policies(env, {"pick": pick})
    env.reset()
    held = env.current_action().clone()
    action = agent.act(env)
    names = list(env.action_joint_names)
    arm = [names.index(j) for j in pick.policy.info["action_joint_names"]]
    base = [i for i in range(env.action_dim) if i not in arm]
    assert torch.all(action[:, arm] == MARK), "the pick policy drives the arm and gripper in the pick phase"
    torch.testing.assert_close(action[:, base], held[:, base])  # the wheels hold (no command from pick)
    env.step(action)
    env.info["phase"][1] = 1  # row 1 enters nav: the nav expert drives the wheels; its arm columns hold
    action = agent.act(env)
    assert torch.all(action[:, arm] == MARK)
    assert torch.all(action[0, base] == 0.0), "row 0 is still picking: its wheels do not turn"
    assert torch.any(action[1, base] != 0.0), "the nav expert drives the base in the nav phase"


def test_wrong_phase_and_missing_terms_are_one_line_errors(coherent_env):
    env = coherent_env
    place = PolicyAgent(ConstantPolicy(env, "GalbotG1-PickToShelf-Place-v0"))
    with pytest.raises(ValueError) as e:
        compose_phase_policies(env, {"pick": place}, sources={"pick": "place.pt"})
    msg = str(e.value)
    assert "\n" not in msg and "place.pt was trained for GalbotG1-PickToShelf-Place-v0" in msg
    assert "phase 'pick'" in msg and "give that phase a checkpoint of GalbotG1-PickToShelf-Pick-v0" in msg
    with pytest.raises(ValueError, match=r"has no phase 'lift'; its phases: pick, nav, place"):
        compose_phase_policies(env, {"lift": place})
    blind = PolicyAgent(ConstantPolicy(env, "GalbotG1-PickToShelf-Pick-v0", images=["front_head_rgb"]))
    with pytest.raises(ValueError) as e:  # trained on the front camera; this env renders none
        compose_phase_policies(env, {"pick": blind}, sources={"pick": "cam.pt"})
    assert "\n" not in str(e.value) and "phase 'pick' (cam.pt)" in str(e.value) and "front_head" in str(e.value)


def test_evaluation_summary_says_where_rows_stop(coherent_env):
    env = coherent_env
    stuck = PolicyAgent(ConstantPolicy(env, "GalbotG1-PickToShelf-Pick-v0"))  # never lifts the bar
    summary = env.evaluate(agent=compose_phase_policies(env, {"pick": stuck}), episodes=2, max_steps=30, progress=False)
    phases = summary["phases"]
    assert list(phases) == ["pick", "nav", "place"]
    assert phases["pick"]["reached"] == 2 and phases["pick"]["passed"] == 0
    assert sum(phases["pick"]["stalled"].values()) == 2  # ran out of steps, or knocked the bar over
    assert set(phases["pick"]["stalled"]) <= {"max_steps", "bar_tipped", "bar_dropped"}
    assert phases["nav"] == phases["place"] == {"reached": 0, "passed": 0, "stalled": {}}
    expert = env.evaluate(agent=compose_phase_policies(env, {}), episodes=2, max_steps=1500, progress=False)
    assert expert["success_rate"] == 1.0
    assert all(p == {"reached": 2, "passed": 2, "stalled": {}} for p in expert["phases"].values())


class CountingPolicy(ConstantPolicy):
    """``ConstantPolicy`` that remembers how many rows each of its re-plans was asked for."""

    def __init__(self, env, component: str):
        super().__init__(env, component)
        self.batches: list[int] = []

    def predict_action(self, history, generator=None):
        self.batches.append(history.shape[0])
        return super().predict_action(history, generator)


def test_a_phase_policy_plans_only_for_the_rows_in_its_phase(coherent_env):
    env = coherent_env
    pick = PolicyAgent(CountingPolicy(env, "GalbotG1-PickToShelf-Pick-v0"))
    agent = compose_phase_policies(env, {"pick": pick})
    env.reset()
    agent.act(env)
    assert pick.policy.batches == [2], "both rows start in pick and plan together"
    env.info["phase"][1] = 1  # row 1 leaves for nav; row 0 picks on
    horizon = pick.policy.cfg.action_horizon
    for _ in range(2 * horizon):
        agent.act(env)
    assert pick.policy.batches[1:] == [1, 1], "one re-plan per action horizon, for row 0 alone"


def test_evaluation_asks_no_plans_for_rows_without_an_episode_left(coherent_env):
    env = coherent_env
    pick = PolicyAgent(CountingPolicy(env, "GalbotG1-PickToShelf-Pick-v0"))
    summary = env.evaluate(agent=compose_phase_policies(env, {"pick": pick}), episodes=1, max_steps=12, progress=False)
    assert len(summary["success_masks"]) == 1
    # one episode on two rows: row 1 never runs one, so every re-plan is row 0's alone
    assert pick.policy.batches and set(pick.policy.batches) == {1}
