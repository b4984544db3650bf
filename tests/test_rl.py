"""PPO through rsl_rl on the batched env, on the CPU at its smallest size: ``newton-lab train-rl`` writes a checkpoint,
its curve, a resume point, a tensorboard log and a run record, and evaluates its actor on held-out episodes; the
same seed trains the same actor; an interrupted run resumes from its last chunk; ``evaluate --checkpoint`` runs the
PPO actor as it runs a diffusion policy; the Prefect flow caches the training; bad input is one line."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

pytestmark = pytest.mark.filterwarnings("ignore:`torch.jit.load` is deprecated")

TASK = "GalbotG1-Reach-v0"
TINY = [
    "--task",
    TASK,
    "--num-envs",
    "4",
    "--device",
    "cpu",
    "--steps-per-env",
    "8",
    "--chunk-iterations",
    "1",
    "--hidden-dims",
    "32",
    "32",
]
TINY_PPO = {"num_envs": 4, "device": "cpu", "chunk_iterations": 1, "num_steps_per_env": 8, "hidden_dims": (32, 32)}


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "newton_lab.cli", *args], cwd=cwd, capture_output=True, text=True, timeout=600
    )


def actor_output(path: Path) -> torch.Tensor:
    ckpt = torch.load(path, weights_only=True)
    actor = torch.jit.load(io.BytesIO(ckpt["actor_script"].numpy().tobytes()))
    return actor(torch.linspace(-1, 1, ckpt["info"]["obs_dim"]).unsqueeze(0))


def train(out: Path, iterations: int, resume: bool = False) -> Path:
    from newton_lab.policies.rl.train import PPOConfig, train_ppo  # deferred: rsl_rl, Warp

    return train_ppo(TASK, PPOConfig(iterations=iterations, **TINY_PPO), out, resume=resume, progress=False)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ppo")
    done = cli(
        "train-rl",
        *TINY,
        "--iterations",
        "2",
        "--output-dir",
        str(tmp / "a"),
        "--run-record",
        str(tmp / "a.json"),
        "--eval-episodes",
        "2",
        cwd=tmp,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return tmp, json.loads(done.stdout.strip().splitlines()[-1])


def test_train_rl_writes_checkpoint_curve_resume_point_log_and_record(run):
    tmp, out = run
    folder = tmp / "a"
    assert out["checkpoint"] == str(folder / "checkpoint.pt") and out["iterations"] == 2
    curve = json.loads((folder / "curve.json").read_text())
    assert [r["iteration"] for r in curve] == [1, 2] and curve[-1]["env_steps"] == 2 * 4 * 8
    assert all(r["env_steps_per_s"] > 0 for r in curve)
    for r in curve:  # where each chunk's seconds went: env steps within the rollout, rollout and update within it
        assert 0 < r["env_step_s"] <= r["rollout_s"] and r["update_s"] > 0
        assert r["rollout_s"] + r["update_s"] <= r["wall_s"] - (curve[0]["wall_s"] if r is not curve[0] else 0) + 0.01
    assert (folder / "resume.pt").is_file() and list(folder.glob("events.out.tfevents.*"))  # tensorboard
    assert not list(folder.glob("model_*.pt"))  # rsl_rl's own snapshots: resume.pt holds the same
    ckpt = torch.load(folder / "checkpoint.pt", weights_only=True)
    assert ckpt["format"] == "newton_lab.policies.rl" and ckpt["info"]["task_id"] == TASK
    assert actor_output(folder / "checkpoint.pt").shape == (1, 7)


def test_its_actor_is_evaluated_on_held_out_episodes_and_recorded(run):
    tmp, out = run
    ev = out["evaluation"]
    assert ev["episodes"] == 2 and ev["eval_seed"] == 10_000 and 0 <= ev["rate"] <= 1
    assert out["env_steps_per_s"] == pytest.approx(out["env_steps"] / out["wall_s"])  # the run's mean
    record = json.loads((tmp / "a.json").read_text())
    assert record["kind"] == "train-rl" and record["command"].startswith(f"newton-lab train-rl --task {TASK}")
    from newton_lab.results import rl_rows

    rows = rl_rows([(tmp / "a.json", record)], tmp)
    assert rows and rows[0][0] == "Reach" and "/ 2** (seed 10000)" in rows[0][7]
    curve = [
        {"iteration": 1, "env_steps": 1000, "wall_s": 10.0, "success_rate": 0.5},
        {"iteration": 2, "env_steps": 3000, "wall_s": 20.0, "success_rate": 0.95},
    ]
    record["results"]["curve_rows"] = curve
    (row,) = rl_rows([(tmp / "a.json", record)], tmp)
    assert row[4:7] == ["0.1 k", "0:20", "0:20"]  # run-mean env-steps/s, training time, first >= 90 % row


TIMINGS = ("wall_s", "env_steps_per_s", "env_step_s", "rollout_s", "update_s")


def _curve(folder: Path) -> list[dict]:
    """The run's curve without its timings."""
    rows = json.loads((folder / "curve.json").read_text())
    return [{k: v for k, v in r.items() if k not in TIMINGS} for r in rows]


def test_the_same_seed_trains_the_same_actor_and_a_resumed_run_repeats_the_uninterrupted_one(tmp_path):
    first = train(tmp_path / "b", 2)
    again = train(tmp_path / "c", 2)
    assert torch.equal(actor_output(first), actor_output(again))
    train(tmp_path / "r", 1)
    (tmp_path / "r" / "checkpoint.pt").unlink()  # as a run killed after its first chunk leaves it
    resumed = train(tmp_path / "r", 2, resume=True)
    assert [r["iteration"] for r in _curve(tmp_path / "r")] == [1, 2]
    assert _curve(tmp_path / "r") == _curve(tmp_path / "b")  # the same rows, not a restart
    assert torch.equal(actor_output(resumed), actor_output(first))


def test_a_short_run_raises_the_reward_of_a_step(tmp_path):
    """Six iterations of 16 rows: the mean reward of a step in the last chunk is above the first chunk's (a fixed
    seed, so the run is the same every time)."""
    from newton_lab.policies.rl.train import PPOConfig, train_ppo  # deferred: rsl_rl, Warp

    cfg = PPOConfig(iterations=6, **{**TINY_PPO, "num_envs": 16, "chunk_iterations": 2})
    train_ppo(TASK, cfg, tmp_path / "up", progress=False)
    rewards = [r["mean_step_reward"] for r in _curve(tmp_path / "up")]
    assert len(rewards) == 3 and rewards[-1] > rewards[0], rewards


def test_the_time_budget_cuts_the_last_chunk_to_end_within_it():
    """A chunk is ``chunk_iterations`` long until the budget is near; then it is cut to what fits at the pace of
    the chunk before (seconds per iteration; a resumed run's from its curve), and nothing runs once the budget is
    spent."""
    from newton_lab.policies.rl.train import PPOConfig, _next_chunk, _pace  # deferred: rsl_rl

    cfg = PPOConfig(iterations=1000, chunk_iterations=25, time_budget_s=100.0)
    assert _next_chunk(cfg, done=0, elapsed=0.0, iteration_s=None) == 25  # the first chunk sets the pace
    assert _next_chunk(cfg, done=50, elapsed=80.0, iteration_s=0.4) == 25  # 25 x 0.4 s fit in the 20 s left
    assert _next_chunk(cfg, done=75, elapsed=90.0, iteration_s=0.4) == 25
    assert _next_chunk(cfg, done=100, elapsed=95.0, iteration_s=0.4) == 12  # 5 s left: 12 x 0.4 s
    assert _next_chunk(cfg, done=112, elapsed=99.9, iteration_s=0.4) == 0
    assert _next_chunk(cfg, done=112, elapsed=100.5, iteration_s=0.4) == 0
    assert _next_chunk(PPOConfig(iterations=110, chunk_iterations=25), done=100, elapsed=1e6, iteration_s=9.0) == 10
    curve = [{"iteration": 25, "wall_s": 12.0}, {"iteration": 50, "wall_s": 22.0}]
    assert _pace(curve) == pytest.approx(0.4) and _pace(curve[:1]) == pytest.approx(0.48) and _pace([]) is None


def test_episode_length_s_sets_the_time_limit_of_the_training_episodes(tmp_path):
    """Reach's own limit (12 s, 240 steps) ends no episode in 16 steps a row; a 0.5 s limit (10 steps) ends one on
    every row, as time-outs (the curve counts them, and the tensorboard log has the success rate of the iteration
    they ended in); a limit <= 0 is refused by make_env in one line."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from newton_lab.envs import make_env  # deferred: Warp
    from newton_lab.policies.rl.train import PPOConfig, train_ppo  # deferred: rsl_rl, Warp

    ended = {}
    for name, limit in (("task", None), ("short", 0.5)):
        cfg = PPOConfig(iterations=2, episode_length_s=limit, **{**TINY_PPO, "chunk_iterations": 2})
        train_ppo(TASK, cfg, tmp_path / name, progress=False)
        ended[name] = sum(r["episodes"] for r in _curve(tmp_path / name))
    assert ended == {"task": 0, "short": TINY_PPO["num_envs"]}, ended
    log = EventAccumulator(str(tmp_path / "short"))
    log.Reload()
    assert [s.step for s in log.Scalars("Episode/success_rate")] == [1]  # steps 9-16 are the second iteration
    with pytest.raises(ValueError, match="episode_length_s must be > 0"):
        make_env(TASK, episode_length_s=0.0)


def test_evaluate_runs_the_ppo_actor_and_refuses_another_task(run):
    tmp, out = run
    done = cli(
        "evaluate",
        "--task",
        TASK,
        "--checkpoint",
        out["checkpoint"],
        "--episodes",
        "2",
        "--num-envs",
        "2",
        "--device",
        "cpu",
        "--max-steps",
        "20",
        "--randomize",
        cwd=tmp,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert summary["episodes"] == 2 and 0.0 <= summary["success_rate"] <= 1.0
    wrong = cli(
        "evaluate", "--task", "GalbotG1-PickCube-v0", "--checkpoint", out["checkpoint"], "--device", "cpu", cwd=tmp
    )
    assert wrong.returncode == 2 and f"was trained for {TASK}" in wrong.stderr and "Traceback" not in wrong.stderr


def test_train_rl_refusals_are_one_line(run, tmp_path):
    tmp, _ = run
    finished = cli("train-rl", *TINY, "--iterations", "1", "--output-dir", str(tmp / "a"), cwd=tmp_path)
    assert finished.returncode == 2 and "holds a finished run" in finished.stderr, finished.stderr[-2000:]
    nothing = cli("train-rl", *TINY, "--output-dir", str(tmp_path / "none"), "--resume", cwd=tmp_path)
    assert nothing.returncode == 2 and "nothing to resume" in nothing.stderr, nothing.stderr[-2000:]
    assert "Traceback" not in finished.stderr + nothing.stderr


def test_the_train_rl_flow_trains_evaluates_records_and_is_cached(tmp_path):
    """The Prefect flow: PPO as a cached stage, then the actor on held-out episodes, and a run record."""
    from newton_lab.flows import settings

    settings.configure(tmp_path / "prefect_home")
    from newton_lab.flows.rl import train_rl  # deferred: imports Prefect (after settings.configure)
    from prefect.testing.utilities import prefect_test_harness  # deferred: Prefect reads settings.configure's home

    ppo = {**TINY_PPO, "iterations": 1, "hidden_dims": [32, 32]}
    with prefect_test_harness(server_startup_timeout=120):
        first = train_rl(TASK, ppo, out=str(tmp_path / "out"), eval_episodes=2, eval_max_steps=20)
        again = train_rl(TASK, ppo, out=str(tmp_path / "out"), eval_episodes=2, eval_max_steps=20)
    assert first["stage_states"]["train"] == ["Completed"] and again["stage_states"]["train"] == ["Cached"]
    assert first["evaluation"]["episodes"] == 2 and first["checkpoint"]["kind"] == "rl checkpoint"
    record = json.loads(Path(first["record"]).read_text())
    assert record["kind"] == "train-rl" and record["results"]["success"]["eval_seed"] == 10_000
    assert record["results"]["iterations"] == 1 and len(record["results"]["curve_rows"]) == 1


def test_domain_randomization_of_the_training_rows_is_physics_only_and_recorded(tmp_path):
    """``--domain-randomize`` draws each training row's physics (``envs.perturb.randomize_env``) and the checkpoint's
    config records the levels; a camera axis is refused in one line (the rows render no cameras)."""
    from newton_lab.commands.rl import TrainRLArgs
    from newton_lab.policies.rl.train import PPOConfig, train_ppo  # deferred: rsl_rl, Warp

    assert TrainRLArgs(domain_randomize="object_mass=mild,friction=0.5").ppo_config().domain_randomize == {
        "object_mass": 1.5,
        "friction": 0.5,
    }
    with pytest.raises(ValueError, match="render no cameras"):
        TrainRLArgs(domain_randomize="camera_shift=mild").ppo_config()
    cfg = PPOConfig(iterations=1, domain_randomize={"friction": 0.5}, **TINY_PPO)
    path = train_ppo(TASK, cfg, tmp_path / "dr", progress=False)
    assert torch.load(path, weights_only=False)["config"]["domain_randomize"] == {"friction": 0.5}


def test_the_vec_env_counts_on_the_device_and_refuses_non_finite_actions_once_an_iteration():
    """PPO's vec env steps without the env's per-step host check of the actions: a NaN action is counted on the
    device and ``take_iteration_counts`` (read once an iteration) raises one line for it; the iteration's ended
    episodes come with their mean return and length."""
    from newton_lab.envs import make_env  # deferred: Warp
    from newton_lab.policies.rl.vec_env import RslRlVecEnv

    env = make_env(TASK, num_envs=2, device="cpu", cameras=False, episode_length_s=0.15)  # 3 steps
    vec = RslRlVecEnv(env)
    zeros = torch.zeros(2, env.action_dim)
    for _ in range(3):
        vec.step(zeros)
    counts = vec.take_iteration_counts()
    assert counts["episodes"] == 2 and counts["mean_length"] == 3 and counts["mean_return"] is not None, counts
    bad = zeros.clone()
    bad[1, 0] = float("nan")
    vec.step(bad)
    with pytest.raises(ValueError, match=r"^actions contain NaN or inf in 1 steps of this PPO iteration; [^\n]+$"):
        vec.take_iteration_counts()
    assert vec.take_iteration_counts()["episodes"] == 0  # the count was reset with the refusal


def test_joint_state_adds_the_commanded_joints_velocities_and_targets_for_training_and_evaluation(tmp_path):
    """``joint_state``: the actor's input is the task's observation, then each action column's joint velocity and
    current target (the env's own readings); a checkpoint trained so is evaluated with the same input."""
    from newton_lab.envs import make_env  # deferred: Warp
    from newton_lab.policies.rl.agent import RLPolicyAgent
    from newton_lab.policies.rl.train import PPOConfig, train_ppo
    from newton_lab.policies.rl.vec_env import RslRlVecEnv

    env = make_env("GalbotG1-LiftCube-v0", num_envs=2, device="cpu", cameras=False)
    vec = RslRlVecEnv(env, joint_state=True)
    obs, *_ = vec.step(torch.full((2, env.action_dim), 0.5))
    policy, names = obs["policy"], env.action_joint_names
    assert policy.shape == (2, env.obs.shape[1] + 2 * env.action_dim)
    torch.testing.assert_close(policy[:, : env.obs.shape[1]], env.obs)
    torch.testing.assert_close(policy[:, env.obs.shape[1] : -env.action_dim], env.joints.velocities(names))
    torch.testing.assert_close(policy[:, -env.action_dim :], env.current_action())
    assert float(env.joints.velocities(names).abs().max()) > 0  # the arm moved: the velocities are not all 0

    path = train_ppo(TASK, PPOConfig(iterations=1, joint_state=True, **TINY_PPO), tmp_path / "js", progress=False)
    reach = make_env(TASK, num_envs=2, device="cpu", cameras=False, seed=3, randomize=True)
    summary = reach.evaluate(agent=RLPolicyAgent.from_checkpoint(path), episodes=2, max_steps=5, progress=False)
    assert summary["episodes"] == 2


def test_delta_joint_mode_steps_each_arm_target_from_the_current_one_within_its_box():
    """``joint_mode="delta"``: an action of 1 moves every absolute arm target by ``relative_scale`` from the env's
    current target (the gripper column keeps its span), never past ``delta_range`` from the start posture nor, by
    default, past the joint's range; the env's reset puts the targets back at the start posture; without the current
    targets the map refuses."""
    from newton_lab.envs import make_env  # deferred: Warp
    from newton_lab.policies.rl.actions import ActionMap, ActionScales

    env = make_env("GalbotG1-LiftCube-v0", num_envs=2, device="cpu", cameras=False)  # seven arm joints, a gripper
    env.reset()
    amap = ActionMap(env, ActionScales(joint_mode="delta", delta_range=0.12))
    arm = amap.stepped
    assert arm is not None and int(arm.sum()) == 7 and not bool(arm[-1])
    ones = torch.ones(2, env.action_dim)
    first = amap(ones, env.current_action())
    torch.testing.assert_close(first[:, arm], (amap.rest + 0.05)[arm].expand(2, -1))
    assert float(first[0, -1]) == pytest.approx(env.robot.gripper_closed)
    for _ in range(4):  # 4 steps of 0.05 rad: stopped at 0.12 rad from the start posture
        env.step(amap(ones, env.current_action()))
    torch.testing.assert_close(env.current_action()[:, arm], (amap.rest + 0.12)[arm].expand(2, -1))
    env.reset()
    torch.testing.assert_close(env.current_action()[:, arm], amap.rest[arm].expand(2, -1))
    ranged = ActionMap(env, ActionScales(joint_mode="delta"))  # no box: the joints' ranges
    lower = env.model.joint_limit_lower.numpy()[[env.sim.layout.joints.dof[j] for j in env.action_joint_names[:7]]]
    torch.testing.assert_close(ranged.low[arm], torch.as_tensor(lower))
    assert bool((ranged.low[arm] < amap.rest[arm] - 1.0).any())  # wider than the old 1 rad box somewhere
    with pytest.raises(ValueError, match="current=env.current_action"):
        amap(ones)
    with pytest.raises(ValueError, match="joint_mode must be one of absolute, delta"):
        ActionScales(joint_mode="velocity")


def test_a_delta_mode_actor_is_evaluated_with_its_mode(tmp_path):
    """The checkpoint keeps the joint mode (a dict of scales is taken, as the Prefect flow passes it): the
    evaluation agent steps the arm from the current targets as the training did; resuming in another mode is
    refused."""
    from newton_lab.envs import make_env  # deferred: Warp
    from newton_lab.policies.rl.agent import RLPolicyAgent
    from newton_lab.policies.rl.train import PPOConfig, train_ppo  # deferred: rsl_rl, Warp

    cfg = PPOConfig(iterations=1, scales={"joint_mode": "delta"}, **TINY_PPO)
    path = train_ppo(TASK, cfg, tmp_path / "delta", progress=False)
    env = make_env(TASK, num_envs=2, device="cpu", cameras=False)
    env.reset()
    agent = RLPolicyAgent.from_checkpoint(path)
    action = agent.act(env)
    assert agent.action_map.scales.joint_mode == "delta"
    step = (action - env.current_action())[:, agent.action_map.stepped]
    assert float(step.abs().max()) <= 0.05 + 1e-6
    (path.parent / "checkpoint.pt").rename(path.parent / "kept.pt")  # an interrupted run: only resume.pt
    with pytest.raises(ValueError, match="joint_mode delta; resume it with that mode"):
        train_ppo(TASK, PPOConfig(iterations=2, **TINY_PPO), tmp_path / "delta", resume=True, progress=False)
