"""Every registered task's expert on randomised episodes (every sorting object of SortToShelf): it succeeds in
every episode. Task terms are generic and shared, so a change to one shows here for every task that uses it;
``tools/expert_success.py`` prints the same figures for more episodes."""

from __future__ import annotations

import pytest

import newton_lab.tasks  # noqa: F401  (registers every task id)
from newton_lab.agents import expert_agent
from newton_lab.envs import make_env
from newton_lab.task_api.registry import list_tasks, lookup


def _cases() -> list[tuple[str, dict]]:
    """(task id, options) of every task with an expert (its own, or its phases' for a coherent task), once per
    value of each option with choices."""
    cases = []
    for task_id in list_tasks():
        spec = lookup(task_id)
        if spec.expert is None and not spec.cfg().phases:  # the operator's variant: no expert
            continue
        cases += [(task_id, s) for s in spec.choice_sets()]
    return cases


@pytest.mark.parametrize(("task_id", "options"), _cases(), ids=lambda v: v if isinstance(v, str) else
                         "-".join(map(str, v.values())) or "default")
def test_expert_succeeds_in_every_randomised_episode(task_id, options):
    env = make_env(task_id, num_envs=2, device="cpu", seed=100, randomize=True, task_options=options, cameras=False)
    assert env.step_graph is not None, f"{task_id}: its step is not one captured graph"
    summary = env.evaluate(agent=expert_agent(env), episodes=4, max_steps=3000, progress=False)
    assert summary["success_rate"] == 1.0, (task_id, options, summary["termination_reasons"])


def test_tasks_without_an_expert_step_as_one_captured_graph():
    """The tasks the expert test leaves out (the operator's variants) are captured too: with it, every
    registered task's step is asserted to be one graph (a capture failure would only warn and step eagerly)."""
    left_out = [t for t in list_tasks() if lookup(t).expert is None and not lookup(t).cfg().phases]
    for task_id in left_out:
        env = make_env(task_id, num_envs=1, device="cpu", seed=0, cameras=False)
        assert env.step_graph is not None, f"{task_id}: its step is not one captured graph"


def test_a_step_aiming_where_the_last_one_did_reuses_its_joints(monkeypatch):
    """PickCube's plan has six IK targets, the last (open the gripper) at the pose of the one before: a re-plan
    solves five, and the release waypoint holds the descend waypoint's joints exactly."""
    from newton_lab.robots.g1.kinematics import TcpKinematics

    env = make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=0, randomize=True, cameras=False)
    agent = expert_agent(env)
    first_solves = []
    solve = TcpKinematics.solve

    def counting(self, q, pos, quat, *, iterations=48):
        if iterations == agent.ik_iterations:  # refinements of rows still off are not counted
            first_solves.append(len(q))
        return solve(self, q, pos, quat, iterations=iterations)

    monkeypatch.setattr(TcpKinematics, "solve", counting)
    env.reset()
    agent.act(env)
    names = [s.name for s in agent.plan.steps]
    assert sum(s.target is not None for s in agent.plan.steps) == 6 and len(first_solves) == 5
    way = agent._waypoints.numpy()
    descend, release = names.index("descend_to_target"), names.index("open_left_gripper")
    assert (way[:, release, :7] == way[:, descend, :7]).all()
    assert way[0, release, 7] != way[0, descend, 7]  # the gripper opens there
