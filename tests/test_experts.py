"""Every registered task's expert on randomised episodes (every sorting object of SortToShelf): it succeeds in
every episode. Task terms are generic and shared, so a change to one shows here for every task that uses it;
``tools/expert_success.py`` prints the same figures for more episodes."""

from __future__ import annotations

import newton_lab.tasks  # noqa: F401  (registers every task id)
import pytest

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


@pytest.mark.parametrize(
    ("task_id", "options"),
    _cases(),
    ids=lambda v: v if isinstance(v, str) else "-".join(map(str, v.values())) or "default",
)
def test_expert_succeeds_in_every_randomised_episode(task_id, options):
    env = make_env(task_id, num_envs=2, device="cpu", seed=100, randomize=True, task_options=options, cameras=False)
    assert env.sim.step_graph is not None, f"{task_id}: its step is not one captured graph"
    summary = env.evaluate(agent=expert_agent(env), episodes=4, max_steps=3000, progress=False)
    assert summary["success_rate"] == 1.0, (task_id, options, summary["termination_reasons"])


def test_tasks_without_an_expert_step_as_one_captured_graph():
    """The tasks the expert test leaves out (the operator's variants) are captured too: with it, every
    registered task's step is asserted to be one graph (a capture failure would only warn and step eagerly)."""
    left_out = [t for t in list_tasks() if lookup(t).expert is None and not lookup(t).cfg().phases]
    for task_id in left_out:
        env = make_env(task_id, num_envs=1, device="cpu", seed=0, cameras=False)
        assert env.sim.step_graph is not None, f"{task_id}: its step is not one captured graph"


def test_restarted_rows_wait_for_a_batched_plan_holding_their_reset_targets():
    """``PlannerAgent(replan_batch=4, replan_wait=3)``: a row whose episode restarts holds its reset targets until
    four rows wait or the oldest has held for three calls, then they are planned together; the expert still
    succeeds in every episode, and the episode of a row that waited starts over when its plan begins (the
    lengths are those of planning at once). Below 128 rows the default plans each
    restarted row at once."""
    import torch

    from newton_lab.agents.planner.agent import PlannerAgent

    task = "GalbotG1-PickCube-v0"
    env = make_env(task, num_envs=4, device="cpu", seed=100, randomize=True, cameras=False)
    assert PlannerAgent.from_task(task).replan_batch is None
    agent = PlannerAgent.from_task(task, replan_batch=4, replan_wait=3)
    env.reset()
    agent.reset()
    hold = env.current_action().clone()
    first = agent.act(env)  # four fresh rows: one batch, planned at once
    assert (agent._waiting_since < 0).all() and not torch.equal(first, hold)
    env.reset([1])
    agent.act(env)
    assert list(map(int, (agent._waiting_since >= 0).nonzero()[0])) == [1]
    torch.testing.assert_close(agent.act(env)[1], env.current_action()[1])  # still waiting, holding
    agent.act(env)
    assert (agent._waiting_since >= 0).sum() == 1
    agent.act(env)
    assert (agent._waiting_since < 0).all()  # held for 3 calls: planned alone at the 4th
    runs = [
        make_env(task, num_envs=4, device="cpu", seed=100, randomize=True, cameras=False).evaluate(
            agent=PlannerAgent.from_task(task, replan_batch=batch), episodes=8, max_steps=1500, progress=False
        )
        for batch in (None, 4)
    ]
    assert runs[0]["success_rate"] == runs[1]["success_rate"] == 1.0, runs
    # an episode starts over when its plan begins (rollout: PlannerAgent.holding): the wait is not counted
    assert abs(runs[1]["average_length"] - runs[0]["average_length"]) <= 1.0, runs


def test_a_step_that_repeats_the_last_pose_reuses_its_ik_solution():
    """PickCube opens the gripper where it lowered the cube to, and StackCube releases each cube where it lowered
    it: the planner solves such a pose once (one IK solve fewer per plan) and the two waypoints are the same joints,
    bit for bit."""
    import numpy as np

    from newton_lab.agents.planner.agent import PlannerAgent

    env = make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=3, randomize=True, cameras=False)
    agent = PlannerAgent.from_task(env.task_id)
    env.reset()
    agent.act(env)
    names = [s.name for s in agent.plan.steps]
    way = agent._waypoints.numpy()
    descend, release = names.index("lower_onto_target"), names.index("open_left_gripper")
    assert np.array_equal(way[:, descend, :7], way[:, release, :7])
    assert (way[:, descend, 7] != way[:, release, 7]).all()  # only the gripper differs


def test_the_gather_kernel_takes_the_arm_length_from_its_columns():
    """An arm of 3 joints (another robot's binding): the waypoints hold 3 joints then the gripper, and the gather
    writes those 3 columns and the gripper's, nothing of a 7-joint arm."""
    import numpy as np
    import warp as wp
    from newton_lab.kernels.planner import gather_plan_actions

    arr = lambda a, t=float: wp.array(np.asarray(a), dtype=t, device="cpu")  # noqa: E731
    way = np.array([[[0.5, 0.6, 0.7, 1.1]]], dtype=np.float32)  # one segment: 3 joints, gripper 1.1
    act = wp.full((1, 6), -9.0, dtype=float, device="cpu")
    wp.launch(
        gather_plan_actions,
        dim=1,
        device="cpu",
        inputs=[
            arr(way),
            arr(np.zeros((1, 3))),
            arr([[0]], int),
            arr([[1]], int),
            arr([[-1]], int),
            arr([1], int),
            arr([1], int),
            arr([0], int),
            arr(np.zeros((1, 5))),
            arr([0, 1, 2], int),
            0.01,
            arr([1, 2, 3], int),
            5,
            act,
        ],
    )
    np.testing.assert_allclose(act.numpy()[0], [-9.0, 0.5, 0.6, 0.7, -9.0, 1.1])


def test_a_target_settles_until_the_arm_reaches_it_and_in_full_before_the_gripper_opens():
    """The gather kernel: in its settle frames a segment ends as soon as every arm joint is within the tolerance
    (the next segment's first frame is written, the cursor jumps there), and holds while it is not; a segment with
    no settle (``-1``) holds its frames. The expert's plan: settles end early except before the gripper opens, so a
    PickCube episode is shorter than with the fixed 12 frames (``settle_tolerance=0``) and succeeds as often."""
    import dataclasses

    import numpy as np
    import warp as wp
    from newton_lab.kernels.planner import gather_plan_actions

    from newton_lab.agents.planner.agent import PlannerAgent

    def gather(q_now: float, settle_at: int, cursor: int) -> tuple[np.ndarray, int]:
        way = np.zeros((1, 2, 8), dtype=np.float32)
        way[0, 0, :7], way[0, 1, :7] = 0.5, 1.5  # segment 0 moves to 0.5 in 2 frames, segment 1 to 1.5 in 4
        arr = lambda a, t=float: wp.array(np.asarray(a), dtype=t, device="cpu")  # noqa: E731
        cur, act = arr([cursor], int), wp.zeros((1, 8), dtype=float, device="cpu")
        wp.launch(
            gather_plan_actions,
            dim=1,
            device="cpu",
            inputs=[
                arr(way),
                arr(np.zeros((1, 7))),
                arr([[0, 14]], int),
                arr([[2, 4]], int),
                arr([[settle_at, -1]], int),
                arr([2], int),
                arr([18], int),
                cur,
                arr(np.full((1, 9), q_now)),
                arr(np.arange(7), int),
                0.01,
                arr(np.arange(7), int),
                7,
                act,
            ],
        )
        return act.numpy()[0, :7], int(cur.numpy()[0])

    reached, far = gather(0.495, 2, 2), gather(0.4, 2, 2)
    np.testing.assert_allclose(reached[0], 0.75)  # segment 1's first frame: a quarter of the way on
    assert reached[1] == 15
    np.testing.assert_allclose(far[0], 0.5)  # not there yet: holds the target
    assert far[1] == 3
    assert gather(0.5, -1, 2)[1] == 3  # no settle: every frame held

    task = "GalbotG1-PickCube-v0"
    expert = PlannerAgent.from_task(task).plan
    fixed = dataclasses.replace(expert, settle_tolerance=0.0)
    runs = [
        make_env(task, num_envs=4, device="cpu", seed=100, randomize=True, cameras=False).evaluate(
            agent=PlannerAgent(plan), episodes=8, max_steps=1500, progress=False
        )
        for plan in (expert, fixed)
    ]
    assert runs[0]["success_rate"] == runs[1]["success_rate"] == 1.0, runs
    assert runs[0]["average_length"] < runs[1]["average_length"] - 10, runs
