"""The three tasks on real physics: the planner solves them, and success fires only when it should."""

from __future__ import annotations

import numpy as np
import torch
import warp as wp
from conftest import run_until_done

from newton_lab.agents import PlannerAgent


def _place(env, row: int, name: str, pos, quat=(0.0, 0.0, 0.0, 1.0)) -> None:
    """Teleport a dynamic entity (writes its free-joint coordinates; the solver picks them up)."""
    e = env.task.entities[name]
    c = env.sim.layout.entity_coord[e.slot]
    q = wp.to_torch(env.state.joint_q).view(env.num_envs, -1)
    q[row, c : c + 7] = torch.tensor([*pos, *quat])
    wp.to_torch(env.state.joint_qd).view(env.num_envs, -1)[row] = 0.0


def _gripper_action(env, value: float):
    a = env.current_action()
    a[:, env.action_joint_names.index("left_gripper_joint")] = value
    return a


def test_pick_cube_planner_lifts_and_places(pick_env):
    env = pick_env
    result, poses, signals = run_until_done(env, PlannerAgent.from_task(env.task_id), 400)
    assert [r[:2] for r in result] == [(True, "success"), (True, "success")]
    cube = env.task.entities["cube"].slot
    z = poses[:, :, cube, 2]
    grasped = signals[:, :, env.task.signal_names.index("grasped_cube")] > 0.5
    for row in range(2):
        assert grasped[:, row].any()
        assert float(z[grasped[:, row], row].max()) > 0.125 + 0.08  # lifted while grasped


def test_pick_cube_success_only_on_the_block_with_open_gripper(pick_env):
    env = pick_env
    env.reset()
    block = env.buffers.entity_poses[0, env.task.entities["blue_block"].slot, :3].tolist()
    on_block = (block[0], block[1], block[2] + 0.035)
    cases = {
        "on block, open": (on_block, 0.0, True),
        "on block, closing": (on_block, 1.2, False),
        "beside block": ((block[0], block[1] + 0.2, 0.125), 0.0, False),
        "above block": ((block[0], block[1], block[2] + 0.12), 0.0, False),
    }
    for name, (pos, grip, expect) in cases.items():
        env.reset()
        _place(env, 0, "cube", pos)
        _, _, term, _, info = env.step(_gripper_action(env, grip))
        assert bool(info["success"][0]) is expect, name
        assert bool(term[0]) is expect, name
        assert not bool(info["success"][1]), name


def test_stack_cube_planner_builds_the_stack(stack_env):
    env = stack_env
    result, poses, signals = run_until_done(env, PlannerAgent.from_task(env.task_id), 900)
    assert result[0][:2] == (True, "success")
    fired = {n: np.nonzero(signals[:, 0, k].numpy() > 0.5)[0] for k, n in enumerate(env.task.signal_names)}
    first = {n: (idx[0] if len(idx) else None) for n, idx in fired.items()}
    # the last subtask's signal is the success step itself, which ends (and resets) the episode
    assert first["cube_2_grasped"] < first["cube_2_on_cube_1"] < first["cube_3_grasped"], first


def test_stack_success_needs_the_full_stack(stack_env):
    env = stack_env
    base = (-0.30, 0.15, 0.125)
    env.reset()
    _place(env, 0, "cube_1", base)
    _place(env, 0, "cube_2", (base[0], base[1], base[2] + 0.05))
    _place(env, 0, "cube_3", (-0.22, 0.25, 0.125))
    _, reward, term, _, info = env.step(_gripper_action(env, 0.0))
    sig = dict(zip(env.task.signal_names, info["signals"][0].tolist()))
    assert sig["cube_2_on_cube_1"] == 1.0 and sig["cube_3_on_cube_2"] == 0.0
    assert not bool(info["success"][0]) and not bool(term[0])
    env.reset()
    _place(env, 0, "cube_1", base)
    _place(env, 0, "cube_2", (base[0], base[1], base[2] + 0.05))
    _place(env, 0, "cube_3", (base[0], base[1], base[2] + 0.10))
    _, reward, term, _, info = env.step(_gripper_action(env, 0.0))
    assert bool(info["success"][0]) and bool(term[0])
    assert abs(float(reward[0]) - 1.0) < 1e-5  # the dense reward's maximum (every stage done)
    # the success step resets the row: its observation signals show the new episode, the step signals the stack
    step_sig = dict(zip(env.task.signal_names, info["step_signals"][0].tolist()))
    assert step_sig["cube_3_on_cube_2"] == 1.0 and info["signals"][0].tolist() != info["step_signals"][0].tolist()


def test_stack_cube_runs_as_two_phases_with_stack_cubes_world_and_success():
    """GalbotG1-StackCube-Phased-v0: the first phase ends when cube_2 sits released on cube_1, the second when the
    full stack does (StackCube's own success); its expert is the two subtasks' plans, the second planned from the
    poses the first leaves. The second subtask on its own resets with cube_2 already on cube_1 (here with the
    ``cube_yaw="zero"`` option: every cube at yaw 0)."""
    from newton_lab.agents.experts import expert_agent
    from newton_lab.envs import make_env

    env = make_env("GalbotG1-StackCube-Phased-v0", num_envs=1, device="cpu", seed=3, randomize=True)
    assert env.cfg.phase_names == ["cube_2", "cube_3"] and env.cfg.fixed_base
    env.reset()
    agent, phase, signals = expert_agent(env), [], []
    for _ in range(900):
        _, _, term, trunc, info = env.step(agent.act(env))
        if bool(term[0] | trunc[0]):
            break
        phase.append(int(info["phase"][0]))
        signals.append(info["signals"][0].tolist())
    assert bool(info["success"][0]) and env.task.termination_reasons[int(info["termination_reason"][0])] == "success"
    on_1 = env.task.signal_names.index("cube_2_on_cube_1")
    entered = phase.index(1)
    assert set(phase[:entered]) == {0} and set(phase[entered:]) == {1}
    assert [s[on_1] for s in signals].index(1.0) == entered  # the row moves on in the step cube_2 is let go

    second = make_env(
        "GalbotG1-StackCube-Cube3-v0",
        num_envs=1,
        device="cpu",
        seed=5,
        randomize=True,
        task_options={"cube_yaw": "zero"},
    )
    second.reset()
    pose = {n: second.buffers.entity_poses[0, e.slot].numpy() for n, e in second.task.entities.items()}
    assert np.allclose(pose["cube_2"][:3] - pose["cube_1"][:3], (0.0, 0.0, 0.05), atol=1e-4)
    assert np.linalg.norm(pose["cube_3"][:2] - pose["cube_1"][:2]) >= 0.09
    assert all(np.allclose(pose[c][3:], (0.0, 0.0, 0.0, 1.0), atol=1e-6) for c in ("cube_1", "cube_2", "cube_3"))


def test_reach_planner(reach_env):
    env = reach_env
    result, _, _ = run_until_done(env, PlannerAgent.from_task(env.task_id), 200)
    assert [r[:2] for r in result] == [(True, "success"), (True, "success")]
    goal = env.info["command"]
    assert goal.shape == (2, 3)
