"""The perturbation axes of ``evaluate --perturb``: each changes what it says and nothing else (action noise only the
joint-target columns, latency only when an action arrives, posture noise only the start posture of those joints),
level 0 changes nothing, ``sweep`` gives a row per axis and level, and the command line prints the table."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import torch

from newton_lab.agents import BaseAgent, PerturbedAgent, perturbation_table
from newton_lab.agents.perturbed import joint_target_columns
from newton_lab.task_api.perturbations import AXES, LEVELS, parse_cells


class Ramp(BaseAgent):
    """Holds the start posture, with column 0 raised by 0.001 rad a step: each step's action is told apart."""

    def __init__(self):
        self.calls = 0

    def act(self, env, env_ids=None):
        self.calls += 1
        a = env.current_action().clone()
        a[:, 0] += 0.001 * self.calls
        return a


def test_sweep_is_the_unperturbed_row_then_each_axis_at_each_level():
    cells = parse_cells("sweep")
    assert cells[0].values == {} and len(cells) == 1 + len(AXES) * len(LEVELS)
    assert {(c.label) for c in cells[1:]} == {f"{a}={lv}" for a in AXES for lv in LEVELS}
    together = parse_cells("action_noise=mild, posture_noise=0.1")
    assert together[0].values == {"action_noise": 0.02, "posture_noise": 0.1}
    for bad in ("wind=mild", "action_noise", "action_noise=-1", "action_latency=0.5", "action_noise=1,action_noise=2"):
        with pytest.raises(ValueError, match="--perturb"):
            parse_cells(bad)


def test_action_noise_moves_only_the_joint_target_columns(reach_env):
    env = reach_env
    env.reseed(0)
    inner, noisy = Ramp(), PerturbedAgent(Ramp(), {"action_noise": 0.05}, seed=1)
    cols = joint_target_columns(env)
    a, b = inner.act(env), noisy.act(env)
    others = [c for c in range(env.action_dim) if c not in cols]
    assert cols and torch.all((b - a)[:, cols].abs() > 0) and (b - a)[:, cols].abs().max() < 0.5
    assert torch.equal(a[:, others], b[:, others])
    assert torch.equal(PerturbedAgent(Ramp(), {"action_noise": 0.0}).act(env), a)  # level 0: no change


def test_latency_hands_over_the_action_chosen_steps_earlier(reach_env):
    env = reach_env
    env.reseed(0)
    inner, late = Ramp(), PerturbedAgent(Ramp(), {"action_latency": 2})
    sent, chosen = [], []
    for _ in range(5):
        chosen.append(inner.act(env))
        out = late.act(env)
        sent.append(out)
        env.step(out)
    assert torch.equal(sent[0], chosen[0]) and torch.equal(sent[1], chosen[0])  # the first action repeats
    assert all(torch.equal(sent[t], chosen[t - 2]) for t in range(2, 5))


def test_posture_noise_moves_only_the_start_posture_of_those_joints(reach_env):
    env = reach_env
    env.reseed(0)
    moved_names = [env.action_joint_names[c] for c in joint_target_columns(env)]
    before_q = env.sim.state.joint_q.numpy().copy()
    poses = env.buffers.entity_poses.clone()
    start = env.joints.positions(moved_names).clone()
    agent = PerturbedAgent(Ramp(), {"posture_noise": 0.1}, seed=2)
    agent.act(env)
    after = env.joints.positions(moved_names)
    assert torch.all((after - start).abs() <= 0.1 + 1e-6) and torch.all((after - start).abs() > 0)
    coords = set(env.joints.coords(moved_names))
    q = env.sim.state.joint_q.numpy().reshape(env.num_envs, -1)
    q0 = before_q.reshape(env.num_envs, -1)
    untouched = [c for c in range(q.shape[1]) if c not in coords]
    assert (q[:, untouched] == q0[:, untouched]).all() and torch.equal(env.buffers.entity_poses, poses)
    agent.act(env)  # the same episode: the posture is moved once, at its start
    assert torch.equal(env.joints.positions(moved_names), after)


def test_the_table_has_a_row_per_cell_on_the_same_episodes(reach_env):
    from newton_lab.agents import expert_agent

    env = reach_env
    cells = parse_cells("sweep")[:2] + [parse_cells("action_latency=1")[0]]
    rows = perturbation_table(env, expert_agent(env), cells, seed=0, episodes=2, max_steps=200, progress=False)
    assert [r["perturbation"] for r in rows] == ["none", cells[1].label, "action_latency=1"]
    assert all(r["episodes"] == 2 and 0 <= r["success_rate"] <= 1 for r in rows)
    again = perturbation_table(env, expert_agent(env), cells[:1], seed=0, episodes=2, max_steps=200, progress=False)
    assert again[0]["summary"]["success_masks"] == rows[0]["summary"]["success_masks"]  # same episodes


def test_evaluate_prints_the_perturbation_table(tmp_path):
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "newton_lab.cli",
            "evaluate",
            "--task",
            "GalbotG1-Reach-v0",
            "--episodes",
            "2",
            "--num-envs",
            "2",
            "--device",
            "cpu",
            "--randomize",
            "--max-steps",
            "150",
            "--perturb",
            "action_noise=mild,action_latency=1",
            "--run-record",
            "r.json",
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    (row,) = out["perturbations"]
    assert row["values"] == {"action_noise": 0.02, "action_latency": 1.0} and row["episodes"] == 2
    assert "action_noise=0.02,action_latency=1" in done.stderr
    from newton_lab.results import robustness_rows

    record = json.loads((tmp_path / "r.json").read_text())
    assert record["kind"] == "evaluate" and record["command"].startswith("newton-lab evaluate --task")
    (table_row,) = robustness_rows([(tmp_path / "r.json", record)], tmp_path)
    assert table_row[2] == "expert" and table_row[4] == f"**{row['successes']} / 2**"


def test_a_robustness_row_names_the_phase_policies_it_evaluated(tmp_path):
    """A composed evaluation is shown as its phase policies, from the record or (older records) its command."""
    from newton_lab.results import robustness_rows

    cell = {"perturbation": "camera_shift=2", "episodes": 100, "successes": 60}
    base = {"kind": "evaluate", "task": "GalbotG1-PickToShelf-v0", "device": {"name": "NVIDIA H200"}}
    recorded = {
        **base,
        "command": "newton-lab evaluate --task GalbotG1-PickToShelf-v0",
        "results": {
            "checkpoint": None,
            "phase_checkpoints": {"pick": "a.pt", "place": "b.pt"},
            "perturbations": [cell],
        },
    }
    older = {
        **base,
        "command": "newton-lab evaluate --phase-checkpoint pick=p/a.pt place=p/b.pt --episodes 100",
        "results": {"checkpoint": None, "perturbations": [cell]},
    }
    for record in (recorded, older):
        (row,) = robustness_rows([(tmp_path / "r.json", record)], tmp_path)
        assert row[2] == "phase policies: pick, place" and row[4] == "**60 / 100**"
