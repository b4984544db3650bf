"""Env core on real physics: one fused task kernel per step, graph capture, per-row resets, seeding."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
import warp as wp
from newton_lab.tasks.common.config.g1 import postures

from newton_lab.envs import make_env
from newton_lab.robots.g1 import spec
from newton_lab.task_api.registry import lookup


@pytest.fixture(scope="module")
def eager_env():
    return make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=0, randomize=True, capture=False)


def _q(env):
    return wp.to_torch(env.state.joint_q).view(env.num_envs, -1).clone()


def test_one_task_kernel_launch_per_step(eager_env, monkeypatch):
    launched = []
    real = wp.launch

    def counting(kernel, *args, **kwargs):
        launched.append(kernel)
        return real(kernel, *args, **kwargs)

    monkeypatch.setattr(wp, "launch", counting)
    eager_env.step(eager_env.current_action())
    assert sum(k is eager_env.task.kernels.task for k in launched) == 1
    # the observation kernel runs twice: before the masked reset (``final_obs``, the terminal observation of rows
    # that finish) and after it (``obs``); the fused task logic still runs once
    assert sum(k is eager_env.task.kernels.observe for k in launched) == 2
    assert sum(k is eager_env.task.kernels.reset for k in launched) == 1


def test_step_is_one_captured_graph(pick_env):
    assert pick_env.sim.step_graph is not None


STEP_INFO_KEYS = (
    "success",
    "success_latched",
    "done",
    "termination_reason",
    "episode_length",
    "phase",
    "signals",
    "step_signals",
    "command",
)


def _step_outputs(env, out) -> dict[str, torch.Tensor]:
    """Copies of everything one step hands out: its return values, every info entry, the terminal observation
    and the state reached (the next step overwrites the views)."""
    obs, reward, terminated, truncated, info = out
    assert set(STEP_INFO_KEYS) == set(info), "a new info entry: compare it below too"
    got = {
        "obs": obs,
        "reward": reward,
        "terminated": terminated,
        "truncated": truncated,
        "final_obs": env.buffers.final_obs,
        "joint_q": wp.to_torch(env.state.joint_q),
        "episode_count": env.buffers.episode_count,
        "entity_poses": env.buffers.entity_poses,
        "tcp_pose": env.buffers.tcp_pose,
    }
    got.update({f"info[{k}]": info[k] for k in STEP_INFO_KEYS})
    return {k: (v.clone() if isinstance(v, torch.Tensor) else torch.as_tensor(np.array(v))) for k, v in got.items()}


def test_captured_step_matches_eager(pick_env, eager_env):
    """The captured graph and eager stepping agree on every output of every step, through a row that terminates
    (its cube teleported 60 m: ``diverged``, finite) and a row that times out, and the new episodes after them."""
    env_steps = pick_env.cfg.max_episode_steps
    for env in (pick_env, eager_env):  # seed 0, counters 0 -> the same reset draws, whatever ran on them before
        env.reseed(0)
        # close to the time limit: row 0 is truncated inside the run, row 1 (terminated first) is not
        wp.to_torch(env.task.context.episode_step)[:] = env_steps - 8
    torch.testing.assert_close(_q(pick_env), _q(eager_env))
    counts = pick_env.buffers.episode_count.clone()
    seen = {"terminated": 0, "truncated": 0}
    cube = pick_env.task.entities["cube"].coord
    for t in range(15):
        a = pick_env.current_action()
        a[:, 3] += 0.01 * t
        if t == 3:
            for env in (pick_env, eager_env):
                wp.to_torch(env.state.joint_q).view(env.num_envs, -1)[1, cube] = 60.0
        for env in (pick_env, eager_env):  # outputs only the step writes: a graph that skips one is caught
            for view in (env.buffers.final_obs, env.info["step_signals"], env.reward):
                view.fill_(7.0)
        captured = _step_outputs(pick_env, pick_env.step(a))
        eager = _step_outputs(eager_env, eager_env.step(a.clone()))
        for key, value in captured.items():
            if value.dtype.is_floating_point:
                torch.testing.assert_close(
                    value, eager[key], atol=1e-5, rtol=0, msg=lambda m, k=key, t=t: f"step {t} {k}: {m}"
                )
            else:
                assert torch.equal(value, eager[key]), f"step {t} {key}: {value.tolist()} != {eager[key].tolist()}"
        seen["terminated"] += int(captured["terminated"].sum())
        seen["truncated"] += int(captured["truncated"].sum())
    # not vacuous: the run went through both ends of an episode and the resets after them
    assert seen == {"terminated": 1, "truncated": 1}
    assert (pick_env.buffers.episode_count == counts + 1).all()


def test_captured_step_matches_eager_with_an_exchange_every_substep():
    """``PhysicsCfg(sync_every_substep=True)`` steps each substep as a whole ``solver.step`` (the other loop of
    ``StepLaunches.simulate``): the graph recorded from it runs every one of the ``decimation`` substeps, as eager
    stepping does, so the arm reaches the same coordinates on both."""
    task = "GalbotG1-PickCube-v0"
    physics = dataclasses.replace(lookup(task).make_cfg({}).physics, sync_every_substep=True)
    captured, eager = (
        make_env(
            task, num_envs=1, device="cpu", seed=3, randomize=True, cameras=False, physics=physics, capture=capture
        )
        for capture in (True, False)
    )
    assert captured.sim.step_graph is not None and eager.sim.step_graph is None
    assert captured.sim.physics_exchange == eager.sim.physics_exchange == "substep"
    start = _q(captured)
    torch.testing.assert_close(start, _q(eager))
    for t in range(6):
        a = captured.current_action()
        a[:, :7] += 0.05 * (t + 1)  # the arm joints move towards new targets every step
        captured.step(a)
        eager.step(a.clone())
        torch.testing.assert_close(_q(captured), _q(eager), atol=1e-5, rtol=0, msg=lambda m, t=t: f"step {t}: {m}")
    assert float((_q(captured) - start).abs().max()) > 0.01  # not vacuous: the arm did move


def test_step_returns_views_of_warp_buffers(pick_env):
    obs, reward, terminated, truncated, info = pick_env.step(pick_env.current_action())
    assert obs.data_ptr() == wp.to_torch(pick_env.buffers.arrays.obs).data_ptr()
    assert reward.data_ptr() == wp.to_torch(pick_env.buffers.arrays.reward).data_ptr()
    assert obs.shape == (2, pick_env.task.obs_dim) and terminated.dtype == torch.bool
    assert set(pick_env.task.obs_terms) == {
        "actions",
        "robot_joint_pos",
        "tcp_pose",
        "gripper_pos",
        "cube_pose",
        "blue_block_pos",
    }


def test_reset_touches_only_selected_rows(pick_env):
    env = pick_env
    env.reset()
    a = env.current_action()
    a[:, 0] += 0.3  # swing the shoulder so every row leaves its reset posture
    for _ in range(10):
        env.step(a)
    q_before, body_before = _q(env), wp.to_torch(env.state.body_q).view(2, -1, 7).clone()
    count_before = env.buffers.episode_count.numpy().copy()
    env.reset([1])
    q_after, body_after = _q(env), wp.to_torch(env.state.body_q).view(2, -1, 7)
    assert torch.equal(q_after[0], q_before[0]) and torch.equal(body_after[0], body_before[0])
    arm = env.joints.coords(spec.LEFT_ARM_JOINTS)
    torch.testing.assert_close(q_after[1, arm], torch.tensor(postures.TABLE_TOP_LEFT_ARM), atol=1e-6, rtol=0)
    assert not torch.allclose(q_before[1, arm], q_after[1, arm])
    assert (env.buffers.episode_count.numpy() - count_before).tolist() == [0, 1]
    assert int(env.info["episode_length"][1]) >= 0 and int(wp.to_torch(env.task.context.episode_step)[1]) == 0


def test_randomisation_is_seeded_per_row_and_episode(pick_env, eager_env):
    for env in (pick_env, eager_env):  # same seed and episode counters -> same draws
        env.reseed(0)
    cube = pick_env.task.entities["cube"].slot
    a, b = pick_env.buffers.entity_poses[:, cube, :3].clone(), eager_env.buffers.entity_poses[:, cube, :3].clone()
    torch.testing.assert_close(a, b)
    assert not torch.allclose(a[0], a[1])  # rows draw independently
    assert ((a[:, 0] >= -0.38) & (a[:, 0] <= -0.22) & (a[:, 1] >= 0.12) & (a[:, 1] <= 0.26)).all()
    pick_env.reset()
    assert not torch.allclose(pick_env.buffers.entity_poses[:, cube, :3], a)  # a new episode draws anew


def test_no_randomisation_by_default():
    env = make_env("GalbotG1-PickCube-v0", num_envs=2, device="cpu", seed=5)
    cube = env.buffers.entity_poses[:, env.task.entities["cube"].slot, :3]
    torch.testing.assert_close(cube, torch.tensor([[-0.30, 0.18, 0.125]] * 2), atol=1e-6, rtol=0)


def test_time_out_truncates_and_auto_resets(reach_env):
    from newton_lab.agents import ZeroAgent

    env = reach_env
    env.reset()
    limit = env.cfg.max_episode_steps
    agent = ZeroAgent()
    hold = agent.act(env).clone()
    hold[:, 0] = -1.4  # point the arm away from every goal
    for _ in range(limit - 1):
        _, _, term, trunc, _ = env.step(hold)
        assert not (term | trunc).any()
    _, _, term, trunc, info = env.step(hold)
    assert trunc.all() and not term.any()
    assert [env.task.termination_reasons[int(r)] for r in info["termination_reason"]] == ["time_out", "time_out"]
    assert info["episode_length"].tolist() == [limit, limit]
    assert wp.to_torch(env.task.context.episode_step).tolist() == [0, 0]


def test_kernel_prefetch_imports_mujoco_warp_before_its_thread_starts():
    """The prefetch thread once imported mujoco_warp itself; racing the solver's import on another thread, Python's
    import-deadlock breaker handed a Dask worker a half-initialised module (no ``OverflowType``). The caller's
    thread now imports it before the thread starts (here the thread never starts)."""
    import subprocess
    import sys

    code = (
        "import sys, threading\nfrom newton_lab.envs import prefetch\n"
        "assert 'mujoco_warp' not in sys.modules, 'imported earlier: the test would prove nothing'\n"
        "threading.Thread.start = lambda self: None\nprefetch.prefetch_kernels('cpu')\n"
        "assert hasattr(sys.modules['mujoco_warp'], 'OverflowType')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_kernel_prefetch_compiles_side_by_side_on_a_many_core_gpu_host_only(eager_env):
    """One module at a time for a CPU device (its compile shares the model build's cores), up to 8 at once for a
    CUDA device, leaving a core to the model build; the thread-pool path loads every imported module of the list
    (run here on the CPU with two workers: the kernel cache answers, nothing new is compiled)."""
    from newton_lab.envs.prefetch import PREFETCH_MODULES, _load_all, prefetch_workers

    assert [prefetch_workers(True, 16), prefetch_workers(False, 16), prefetch_workers(False, 4)] == [1, 8, 3]
    assert prefetch_workers(False, 1) == 1
    names = _load_all("cpu", workers=2)
    assert names and set(names) <= set(PREFETCH_MODULES) and "mujoco_warp._src.forward" in names
    assert all(wp.get_module(name).execs for name in names)


def test_each_action_column_is_clipped_to_its_range(eager_env):
    """``apply_actions`` writes ``clamp(scale * a, low, high)`` to each column's joint target: far past the
    gripper's clip (open .. closed) lands on the bound, an unbounded arm column passes through."""
    env, amap = eager_env, eager_env.joints.binding.actions
    env.reset()
    grip = amap.kinds.index("binary")
    assert np.isfinite([amap.low[grip], amap.high[grip]]).all() and amap.high[grip] > amap.low[grip]
    targets = wp.to_torch(env.control.joint_target_q).view(env.num_envs, -1)
    for value, expected in ((50.0, amap.high[grip]), (-50.0, amap.low[grip]), (0.5, 0.5)):
        env.buffers.actions.copy_(env.current_action())
        env.buffers.actions[:, grip] = value
        env.buffers.actions[:, 0] = 0.7  # an absolute arm column, unbounded
        env.sim.apply_actions()
        torch.testing.assert_close(targets[:, int(amap.index[grip])], torch.full((2,), float(expected)))
        torch.testing.assert_close(targets[:, int(amap.index[0])], torch.full((2,), 0.7 * float(amap.scale[0])))
    env.reset()


def test_a_task_whose_step_cannot_be_captured_says_so_and_steps_eagerly(monkeypatch):
    """Where Warp cannot capture the step, the env warns in one line and steps eagerly (correct, slower)."""
    from newton_lab.envs.launches import GraphCaptureWarning

    def refuse(*args, **kwargs):
        raise RuntimeError("graph capture is not supported here")

    monkeypatch.setattr(wp, "ScopedCapture", refuse)
    with pytest.warns(GraphCaptureWarning) as caught:
        env = make_env("GalbotG1-Reach-v0", num_envs=1, device="cpu", seed=0)
    message = str(caught[0].message)
    assert "\n" not in message and "GalbotG1-Reach-v0" in message and "stepping eagerly" in message
    assert "graph capture is not supported here" in message
    assert env.sim.step_graph is None
    assert torch.isfinite(env.step(env.current_action())[0]).all()
