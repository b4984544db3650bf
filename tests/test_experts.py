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
