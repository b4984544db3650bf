"""Dense staged rewards (``tasks.common.rewards``) on real physics: they stay in their documented range [0, 1],
climb along an expert episode and reach their maximum at success."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import warp as wp
from newton_lab.tasks.common.rewards import DENSE_REWARD_MAX, Stage, phased_rewards, staged_rewards

from newton_lab.agents import PlannerAgent, expert_agent

NAV_TASKS = {"GalbotG1-BaseNav-v0", "GalbotG1-PickToShelf-Nav-v0", "GalbotG1-SortToShelf-Nav-v0", "GalbotG1-Reach-v0"}
"""Tasks keeping the reference's distance-shaped rewards (not normalised)."""


def _expert_rewards(env, agent, max_steps: int):
    """Step ``agent`` until every row has ended one episode. Returns per row ``(success, reason, rewards)`` with the
    row's rewards up to and including its last step (the reward of the ending step is that of the terminal state).
    The env is reseeded first: its episodes are those of a fresh env, whatever other tests ran on it before (the
    fixtures are shared, and which tests ran before depends on how xdist spread the modules)."""
    env.reseed(env.seed)
    agent.reset()
    hist, ends = [], [None] * env.num_envs
    for t in range(max_steps):
        _, reward, term, trunc, info = env.step(agent.act(env))
        hist.append(reward.clone())
        for row in np.nonzero((term | trunc).numpy())[0]:
            if ends[row] is None:
                reason = env.task.termination_reasons[int(info["termination_reason"][row])]
                ends[row] = (t, bool(info["success"][row]), reason)
        if all(e is not None for e in ends):
            break
    rewards = torch.stack(hist).numpy()
    assert all(e is not None for e in ends), f"not every row ended in {max_steps} steps: {ends}"
    return [(s, reason, rewards[: t + 1, row]) for row, (t, s, reason) in enumerate(ends)]


def _assert_rises_to_max(success: bool, reason: str, r: np.ndarray) -> None:
    assert success, reason
    assert np.isfinite(r).all()
    assert r.min() >= 0.0 and r.max() <= DENSE_REWARD_MAX + 1e-5, (r.min(), r.max())
    assert r[-1] == pytest.approx(DENSE_REWARD_MAX, abs=1e-5), f"reward at success {r[-1]:.3f}"
    q = max(len(r) // 4, 1)
    first, last = float(r[:q].mean()), float(r[-q:].mean())
    assert last > first + 0.25, f"mean reward first quarter {first:.3f}, last quarter {last:.3f}"


def _place(env, row: int, name: str, pos) -> None:
    """Teleport a dynamic entity (free-joint coordinates, zero velocity; the next step uses them)."""
    c = env.sim.layout.entity_coord[env.task.entities[name].slot]
    wp.to_torch(env.state.joint_q).view(env.num_envs, -1)[row, c : c + 7] = torch.tensor([*pos, 0.0, 0.0, 0.0, 1.0])
    wp.to_torch(env.state.joint_qd).view(env.num_envs, -1)[row] = 0.0


def _step_with_gripper(env, value: float):
    a = env.current_action()
    a[:, env.action_joint_names.index("left_gripper_joint")] = value
    return env.step(a)


# ---------------------------------------------------------------- declarations
def test_every_manipulation_task_declares_a_normalised_dense_reward():
    import newton_lab.tasks  # noqa: F401  (registers the tasks)

    from newton_lab.task_api.registry import list_tasks, lookup

    for task_id in list_tasks():
        if task_id in NAV_TASKS:
            continue
        cfg = lookup(task_id).cfg()
        weights = [t.weight for t in cfg.rewards.values()]
        assert weights and min(weights) > 0, f"{task_id}: no dense reward ({list(cfg.rewards)})"
        if cfg.phases:  # (phase + r_phase) / n: the phase term and each group of phases sharing terms, 1/n each
            groups = {name.split("/")[0] for name in cfg.rewards if "/" in name}  # phases sharing terms: one
            assert sum(weights) == pytest.approx(DENSE_REWARD_MAX * (1 + len(groups)) / len(cfg.phases)), task_id
        else:
            assert sum(weights) == pytest.approx(DENSE_REWARD_MAX), task_id


def test_bad_reward_declarations_fail_in_one_line():
    from newton_lab.tasks.common.terminations import grasped

    grasped_cube = grasped(entity="cube")

    with pytest.raises(ValueError, match="unique stage names"):
        staged_rewards(Stage("a", grasped_cube), Stage("a", grasped_cube))
    with pytest.raises(ValueError, match="build it with staged_rewards"):
        from newton_lab.task_api.cfg import RewardTermCfg

        phased_rewards([("pick", {"x": RewardTermCfg(func=grasped_cube, weight=2.0)})])
    one, other = ({"x": RewardTermCfg(func=grasped_cube, weight=1.0)} for _ in range(2))
    shared = phased_rewards([("pick", one), ("place", other), ("pick", one)])  # two picks share their terms
    assert list(shared) == ["phase", "pick/x", "place/x"] and shared["pick/x"].weight == pytest.approx(1 / 3)
    with pytest.raises(ValueError, match="phases named 'pick' must share one reward dict; name the phases apart"):
        phased_rewards([("pick", one), ("pick", other)])


# ---------------------------------------------------------------- PickCube
def test_pick_cube_reward_rises_along_the_expert_episode(pick_env):
    env = pick_env
    episodes = _expert_rewards(env, PlannerAgent.from_task(env.task_id), 400)
    for success, reason, r in episodes:
        _assert_rises_to_max(success, reason, r)
        # the stages are met in order: near the cube (0.2), grasped (0.4), on the block (0.6), released (1.0)
        first = [int(np.argmax(r >= level - 1e-5)) for level in (0.2, 0.4, 0.6)]
        assert first == sorted(first) and r[first[-1] :].min() >= 0.6 - 1e-5, first


def test_pick_cube_reward_by_state(pick_env):
    env = pick_env
    env.reset()
    block = env.buffers.entity_poses[0, env.task.entities["blue_block"].slot, :3].tolist()
    _place(env, 0, "cube", (block[0], block[1], block[2] + 0.035))  # row 0: released on the block
    _place(env, 1, "cube", (block[0], block[1] + 0.25, 0.125))  # row 1: on the table, far from the open hand
    _, reward, term, _, info = _step_with_gripper(env, 0.0)
    assert bool(info["success"][0]) and not bool(info["success"][1])
    assert float(reward[0]) == pytest.approx(1.0, abs=1e-5)
    assert 0.0 < float(reward[1]) < 0.2  # reaching shaping only


# ---------------------------------------------------------------- StackCube
def test_stack_cube_reward_by_state(stack_env):
    env = stack_env
    base = (-0.30, 0.15, 0.125)
    env.reset()
    _place(env, 0, "cube_1", base)
    _place(env, 0, "cube_2", (base[0], base[1], base[2] + 0.05))
    _place(env, 0, "cube_3", (-0.22, 0.25, 0.125))
    _, reward, _, _, info = _step_with_gripper(env, 0.0)
    assert not bool(info["success"][0])
    assert 4 / 9 <= float(reward[0]) < 5 / 9  # cube_2 stacked and released, cube_3 not reached yet
    env.reset()
    for i in range(3):  # the full stack, released
        _place(env, 0, f"cube_{i + 1}", (base[0], base[1], base[2] + 0.05 * i))
    _, reward, _, _, info = _step_with_gripper(env, 0.0)
    assert bool(info["success"][0]) and float(reward[0]) == pytest.approx(1.0, abs=1e-5)


@pytest.mark.slow
def test_stack_cube_reward_rises_along_the_expert_episode(stack_env):
    ((success, reason, r),) = _expert_rewards(stack_env, PlannerAgent.from_task(stack_env.task_id), 900)
    _assert_rises_to_max(success, reason, r)
    assert r[np.argmax(r >= 4 / 9 - 1e-5) :].min() >= 4 / 9 - 1e-5  # cube_2 stays stacked while cube_3 is moved


# ---------------------------------------------------------------- LiftCube, coherent PickToShelf / SortToShelf
@pytest.mark.slow
def test_lift_cube_reward_rises_along_the_expert_episode():
    from newton_lab.envs import make_env

    env = make_env("GalbotG1-LiftCube-v0", num_envs=1, device="cpu", seed=2, randomize=True)
    ((success, reason, r),) = _expert_rewards(env, expert_agent(env), 400)
    _assert_rises_to_max(success, reason, r)


@pytest.mark.slow
def test_a_gripper_closed_beside_the_cube_or_on_its_corner_earns_no_grasp_reward():
    """The reward's grasp stage needs the fingers stopped by the cube between them (``holding``): closing on
    nothing 4.5 cm beside the cube satisfies ``grasped`` (TCP near, gripper closed), and closing low over the cube's
    corner stops the fingers too (on its edge and the table), but each earns only the reaching stage, while the
    same close on the cube earns the grasp stage."""
    from newton_lab.envs import make_env
    from newton_lab.task_api.motion_plan import AssetTarget, MotionPlan, MotionStep

    def approach_and_close(dx: float, dy: float, dz: float) -> PlannerAgent:
        return PlannerAgent(
            MotionPlan(
                steps=(
                    MotionStep(name="approach", target=AssetTarget("cube", (dx, dy, 0.205))),
                    MotionStep(name="descend", target=AssetTarget("cube", (dx, dy, dz))),
                    MotionStep(name="close", gripper_open=False, hold=30),
                ),
                max_joint_step=0.03,
                settle_steps=12,
            )
        )

    env = make_env("GalbotG1-LiftCube-v0", num_envs=1, device="cpu", seed=0, randomize=True, cameras=False)
    grasped_col = env.task.signal_names.index("grasped_cube")
    fingers = ["left_gripper_joint", "left_gripper_l_finger_joint", "left_gripper_r_finger_joint"]
    best, lag = {}, {}
    for name, offset in (("on", (0.0, 0.0, 0.035)), ("beside", (0.045, 0.0, 0.035)), ("corner", (0.017, 0.02, 0.02))):
        env.reseed(0)
        agent = approach_and_close(*offset)
        agent.reset()
        rewards, grasped = [], []
        for _ in range(110):
            _, reward, *_ = env.step(agent.act(env))
            rewards.append(float(reward[0]))
            grasped.append(bool(env.info["signals"][0, grasped_col]))
        assert any(grasped[-10:]), f"{name}: the gripper never closed near the cube"
        best[name] = max(rewards[-10:])
        master, *slides = env.joints.positions(fingers)[0].tolist()
        lag[name] = min(master * env.robot.finger_travel_per_rad - s for s in slides)  # finger_lag [m]
    stage = 1 / 4  # each of LiftCube's four stages: reaching, grasping, lifting, success
    assert 2 * stage - 1e-5 < best["on"] < 2 * stage + 0.01, best  # reached and holding the cube, lifted 0 of 10 cm
    assert best["beside"] <= stage + 1e-5 and lag["beside"] < 0.005, (best, lag)  # closed on nothing
    assert best["corner"] <= stage + 1e-5 and lag["corner"] > 0.005, (best, lag)  # fingers stopped, no cube between


@pytest.mark.slow
@pytest.mark.parametrize(
    "task_id, options", [("GalbotG1-PickToShelf-v0", None), ("GalbotG1-SortToShelf-v0", {"sorting_object": "red_cube"})]
)
def test_coherent_reward_rises_through_the_phases(task_id, options):
    from newton_lab.envs import make_env

    env = make_env(task_id, num_envs=1, device="cpu", seed=1, randomize=True, task_options=options)
    env.reset()
    agent = expert_agent(env)
    agent.reset()
    rewards, phases = [], []
    for _ in range(700):
        phase = int(env.info["phase"][0])
        _, reward, term, trunc, info = env.step(agent.act(env))
        rewards.append(float(reward[0]))
        phases.append(phase if bool(term[0] | trunc[0]) else int(info["phase"][0]))
        if bool(term[0] | trunc[0]):
            break
    r, phases = np.asarray(rewards), np.asarray(phases)
    _assert_rises_to_max(bool(info["success"][0]), env.task.termination_reasons[int(info["termination_reason"][0])], r)
    for p in range(3):  # phase p's rewards lie in [p/3, (p+1)/3]
        rp = r[phases == p]
        assert len(rp) and rp.min() >= p / 3 - 1e-5 and rp.max() <= (p + 1) / 3 + 1e-5, (p, rp.min(), rp.max())
