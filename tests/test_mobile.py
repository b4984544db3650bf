"""Mobile base, navigation, composition of coherent tasks, scenarios: real physics on CPU Warp."""

from __future__ import annotations

import math
import multiprocessing

import numpy as np
import pytest
import torch
import warp as wp

from newton_lab.robots.g1 import spec
from newton_lab.robots.mecanum import twist_to_wheels_torch
from newton_lab.robots.registry import robot_binding

COHERENT = "GalbotG1-PickToShelf-v0"


def base_twist_to_wheel_velocities(vx: float, vy: float, wz: float, *, num_envs: int) -> torch.Tensor:
    """The G1's four wheel speeds [rad/s] for the base twist (vx, vy [m/s], wz [rad/s]), one row per env: the formula
    the nav agents apply (``robots.mecanum`` with the robot's gains)."""
    twist = torch.tensor([[vx, vy, wz]], dtype=torch.float32).repeat(num_envs, 1)
    return twist_to_wheels_torch(twist, robot_binding("g1").wheel_gains)


@pytest.fixture(scope="module")
def nav_env():
    from newton_lab.envs import make_env

    return make_env("GalbotG1-BaseNav-v0", num_envs=2, device="cpu")


@pytest.fixture(scope="module")
def shelf_env():
    from newton_lab.envs import make_env

    return make_env(COHERENT, num_envs=4, device="cpu", seed=1, randomize=True)


@pytest.fixture(scope="module")
def shelf_run(shelf_env):
    """One coherent episode per row with the default phase agents; per-step phase, bar and TCP history."""
    from newton_lab.agents import TaskFlowAgent

    env = shelf_env
    env.reset()
    agent = TaskFlowAgent.from_env(env)
    bar = env.task.entities["bar"].slot
    phases, bars, tcps, done_at, results = [], [], [], [None] * 4, [None] * 4
    jp = env.task.obs_terms["robot_joint_pos"]
    wheel_cols, base_cols = env.joints.coords(spec.BASE_WHEEL_JOINTS), env.joints.coords(spec.BASE_PLANAR_JOINTS)
    wheel_q, wheel_obs, base_gap = 0.0, 0.0, 0.0
    for t in range(700):
        pre_phase = env.info["phase"].clone()
        _, _, term, trunc, info = env.step(agent.act(env))
        phases.append(torch.where(term | trunc, pre_phase, info["phase"]).clone())
        bars.append(env.buffers.entity_poses[:, bar, :3].clone())
        tcps.append(env.buffers.tcp_pose[:, :3].clone())
        wheels = env.joints.positions(spec.BASE_WHEEL_JOINTS)
        obs_q = env.obs[:, jp]
        wheel_q = max(wheel_q, float(wheels.abs().max()))
        wheel_obs = max(wheel_obs, float(obs_q[:, wheel_cols].abs().max()))
        base_q = env.joints.positions(spec.BASE_PLANAR_JOINTS)
        base_gap = max(base_gap, float((obs_q[:, base_cols] - base_q).abs().max()))
        for r in np.nonzero((term | trunc).numpy())[0]:
            if done_at[r] is None:
                done_at[r] = t
                reason = env.task.termination_reasons[int(info["termination_reason"][r])]
                results[r] = (bool(info["success"][r]), reason)
        if all(d is not None for d in done_at):
            break
    return {
        "phase": torch.stack(phases),
        "bar": torch.stack(bars),
        "tcp": torch.stack(tcps),
        "done_at": done_at,
        "results": results,
        "wheel_q": wheel_q,
        "wheel_obs": wheel_obs,
        "base_gap": base_gap,
    }


# ---------------------------------------------------------------- base kinematics
def test_commanded_twist_moves_base(nav_env):
    env = nav_env
    env.reset()
    vx, vy, wz = 0.2, 0.05, 0.25
    wheels = base_twist_to_wheel_velocities(vx, vy, wz, num_envs=env.num_envs)
    for _ in range(40):  # 2 s at 20 Hz
        env.step(wheels)
    pose = env.joints.positions(spec.BASE_PLANAR_JOINTS)[0].numpy().astype(np.float64)
    # integrate the base-frame twist exactly: a circular arc of radius v / wz
    yaw = wz * 2.0
    x = (vx * math.sin(yaw) + vy * (math.cos(yaw) - 1.0)) / wz
    y = (vx * (1.0 - math.cos(yaw)) + vy * math.sin(yaw)) / wz
    assert np.hypot(pose[0] - x, pose[1] - y) < 0.01, (pose, x, y)
    assert abs(pose[2] - yaw) < 0.02


def test_inactive_wheels_give_zero_twist(nav_env):
    env = nav_env
    env.reset()
    for _ in range(10):
        env.step(torch.zeros(env.num_envs, 4))
    pose = env.joints.positions(spec.BASE_PLANAR_JOINTS)
    assert float(pose.abs().max()) < 1e-3


def test_base_nav_expert_reaches_goal(nav_env):
    from newton_lab.agents import expert_agent

    res = nav_env.evaluate(agent=expert_agent("GalbotG1-BaseNav-v0"), episodes=2, max_steps=240, progress=False)
    assert res["success_rate"] == 1.0


def test_wheel_clip_and_obs_layout(nav_env):
    assert nav_env.action_joint_names == spec.BASE_WHEEL_JOINTS
    assert list(nav_env.task.obs_terms) == ["actions", "base_xy", "goal_xy", "vector_to_goal"]
    assert nav_env.task.obs_dim == 10


# ---------------------------------------------------------------- agents composed per row
class _SpyAgent:
    def __init__(self):
        self.resets = []

    def act(self, env, env_ids=None):
        return env.current_action()

    def reset(self, env_ids=None):
        self.resets.append(None if env_ids is None else sorted(np.asarray(env_ids).tolist()))

    def done(self, env):
        return torch.zeros(env.num_envs, dtype=torch.bool)


def test_sequence_agent_rows_advance_independently(nav_env):
    from newton_lab.agents import SequenceAgent, SequenceStep

    first, second = _SpyAgent(), _SpyAgent()
    row0_done = lambda env: torch.tensor([True, False])  # noqa: E731
    seq = SequenceAgent([SequenceStep("drive", first, row0_done), SequenceStep("posture", second)])
    nav_env.reset()
    seq.act(nav_env)
    assert seq.current_step().tolist() == [1, 0]
    assert second.resets == [[0]], "only the advanced row's next agent is reset"
    seq.act(nav_env)
    assert seq.current_step().tolist() == [1, 0]


def test_sequence_agent_refuses_a_wrong_done_mask(nav_env):
    from newton_lab.agents import SequenceAgent, SequenceStep

    for bad in (torch.tensor([True]), torch.tensor([1.0, 0.0])):
        seq = SequenceAgent([SequenceStep("drive", _SpyAgent(), lambda env, bad=bad: bad)])
        nav_env.reset()
        with pytest.raises(ValueError, match=r"done of sequence step 'drive' must be a \(2,\) bool tensor"):
            seq.act(nav_env)


# ---------------------------------------------------------------- coherent task
def test_union_action_layout(shelf_env):
    env = shelf_env
    assert env.action_joint_names == spec.LEFT_ARM_JOINTS + (spec.LEFT_GRIPPER_JOINT,) + spec.BASE_WHEEL_JOINTS
    assert list(env.joints.action_terms) == ["arm_action", "gripper_action", "base_action"]
    assert [p.name for p in env.cfg.phases] == ["pick", "nav", "place"]


def test_inactive_terms_hold(shelf_env):
    """Phase pick ignores the wheels (base stays); phase nav ignores arm/gripper (targets hold)."""
    env = shelf_env
    env.reset()
    start = env.joints.positions(spec.BASE_PLANAR_JOINTS).clone()
    act = env.current_action()
    act[:, 7] = spec.GRIPPER_CLOSED
    act[:, 8:12] = base_twist_to_wheel_velocities(0.3, 0.0, 0.0, num_envs=env.num_envs)
    for _ in range(5):
        env.step(act)
    assert float((env.joints.positions(spec.BASE_PLANAR_JOINTS) - start).abs().max()) < 1e-3
    tq = wp.to_torch(env.control.joint_target_q).view(env.num_envs, -1)
    assert float(tq[0, env.sim.layout.joints.coord[spec.LEFT_GRIPPER_JOINT]]) == pytest.approx(spec.GRIPPER_CLOSED)
    # row 0 in the nav phase: the arm command is ignored, the wheels drive
    env.reset()
    env.info["phase"][0] = 1
    held = tq[0, [env.sim.layout.joints.coord[j] for j in spec.LEFT_ARM_JOINTS]].clone()
    act = env.current_action()
    act[:, :7] += 0.3
    act[:, 8:12] = base_twist_to_wheel_velocities(0.3, 0.0, 0.0, num_envs=env.num_envs)
    for _ in range(5):
        env.step(act)
    moved = env.joints.positions(spec.BASE_PLANAR_JOINTS)[:, 0] - start[:, 0]
    assert float(moved[0]) > 0.03 and float(moved[1:].abs().max()) < 1e-3
    after = tq[0, [env.sim.layout.joints.coord[j] for j in spec.LEFT_ARM_JOINTS]]
    assert torch.allclose(after, held)
    assert float(tq[1, env.sim.layout.joints.coord["left_arm_joint1"]]) == pytest.approx(float(act[1, 0]))


def test_nav_failure_ends_episode(shelf_env):
    env = shelf_env
    env.reset()
    env.info["phase"][2] = 1
    c = env.sim.layout.entity_coord[env.task.entities["bar"].slot]
    q = wp.to_torch(env.state.joint_q).view(env.num_envs, -1)
    q[2, c : c + 3] = torch.tensor([-1.0, -1.0, 0.1])  # the bar stands on the floor, away from the table
    newton_fk(env)
    _, _, term, _, info = env.step(env.current_action())
    assert bool(term[2]) and not bool(term[0])
    assert env.task.termination_reasons[int(info["termination_reason"][2])] == "nav_bar_dropped"
    assert int(info["phase"][2]) == 0, "the row was reset"


def newton_fk(env):
    import newton

    newton.eval_fk(env.model, env.state.joint_q, env.state.joint_qd, env.state)


@pytest.mark.slow
def test_coherent_rows_in_different_phases(shelf_run):
    phase = shelf_run["phase"]
    assert any(len(set(row.tolist())) > 1 for row in phase), "no step had rows in different phases"
    assert all(r[0] for r in shelf_run["results"]), shelf_run["results"]
    # within each row's episode the phase only ever advances, one at a time
    for r, end in enumerate(shelf_run["done_at"]):
        d = phase[1 : end + 1, r] - phase[:end, r]
        assert int(d.max()) <= 1 and int(d.min()) >= 0
        assert int(phase[end, r]) == 2


@pytest.mark.slow
def test_robot_joint_pos_reads_zero_for_the_wheels(shelf_run, shelf_env):
    """The nav phase turns the wheels (their angles integrate every drive so far), but ``robot_joint_pos`` reads 0
    for them, as on the reference platform, while the base pose next to them is the joint state's own."""
    assert shelf_env.robot.base_wheel_joints == spec.BASE_WHEEL_JOINTS
    assert shelf_run["wheel_q"] > 1.0 and shelf_run["wheel_obs"] == 0.0 and shelf_run["base_gap"] == 0.0


def test_bar_stays_in_hand_from_pick_to_place(shelf_run):
    phase, bar, tcp = shelf_run["phase"], shelf_run["bar"], shelf_run["tcp"]
    for r in range(phase.shape[1]):
        nav = torch.nonzero(phase[:, r] == 1).flatten()
        place = torch.nonzero(phase[:, r] == 2).flatten()
        assert nav.numel() and place.numel()
        span = torch.arange(int(nav[0]), int(place[0]) + 10)
        dist = torch.linalg.norm(bar[span, r] - tcp[span, r], dim=1)
        assert float(dist.max()) < 0.04, f"row {r}: bar left the gripper ({float(dist.max()):.3f} m)"


def test_coherent_records_phase_and_splits(shelf_env, tmp_path):
    from newton_lab.agents import BaseAgent
    from newton_lab.datasets import list_demos, read_dataset_info, read_episode
    from newton_lab.datasets.split import split_by_phase

    env = shelf_env
    env.reset()

    class HoldThenNav(BaseAgent):  # holds still; moves every row to the nav phase after two steps (test only)
        calls = 0

        def act(self, env, env_ids=None):
            HoldThenNav.calls += 1
            if HoldThenNav.calls == 3:
                env.info["phase"][:] = 1
            return env.current_action()

    ref = env.collect(agent=HoldThenNav(), episodes=1, path=tmp_path / "c.hdf5", max_steps=5, progress=False)
    ep = read_episode(ref.path, ref["saved_demo_ids"][0])
    assert ep["datagen"]["phase"].tolist() == [0, 0, 1, 1, 1]
    parts = split_by_phase(ref.path, tmp_path / "split")
    pick, nav = read_episode(parts["pick"].path, 0), read_episode(parts["nav"].path, 0)
    assert pick["actions"].shape == (2, 8) and nav["actions"].shape == (3, 4)
    np.testing.assert_array_equal(nav["actions"], ep["actions"][2:, 8:12])
    assert bool(pick["attrs"]["success"]) and not bool(nav["attrs"]["success"])
    assert read_dataset_info(parts["nav"].path)["task_id"] == "GalbotG1-PickToShelf-Nav-v0"
    assert list_demos(parts["place"].path) == []
    with pytest.raises(FileExistsError):
        split_by_phase(ref.path, tmp_path / "split")
    only = split_by_phase(ref.path, tmp_path / "only", phases=["nav"], workers=1)  # in this process
    assert list(only) == ["nav"] and sorted(p.name for p in (tmp_path / "only").iterdir()) == ["nav.hdf5"]
    np.testing.assert_array_equal(read_episode(only["nav"].path, 0)["actions"], nav["actions"])
    with pytest.raises(ValueError, match="has no phase 'grab'; its phases: pick, nav, place"):
        split_by_phase(ref.path, tmp_path / "none", phases=["grab"])
    assert not (tmp_path / "none").exists()
    # inside a daemonic process (a Dask worker's), which may not start the per-phase writers: it writes them itself
    worker = multiprocessing.get_context("spawn").Process(
        target=split_by_phase, args=(ref.path, tmp_path / "daemon"), daemon=True
    )
    worker.start()
    worker.join(300)
    assert worker.exitcode == 0 and sorted(p.name for p in (tmp_path / "daemon").iterdir()) == [
        "nav.hdf5",
        "pick.hdf5",
        "place.hdf5",
    ]


# ---------------------------------------------------------------- scenarios
def test_scenario_round_trip(tmp_path):
    from newton_lab.envs import make_env
    from newton_lab.envs.scenario import capture_scenario, load_scenario

    env = make_env("GalbotG1-PickToShelf-Nav-v0", num_envs=1, device="cpu")
    wheels = base_twist_to_wheel_velocities(0.2, 0.0, 0.3, num_envs=1)
    for _ in range(10):
        env.step(wheels)
    q = wp.to_torch(env.state.joint_q).view(1, -1)[0].numpy().copy()
    path = capture_scenario(env, 0).save(tmp_path / "end.yaml")
    with pytest.raises(FileExistsError):
        capture_scenario(env, 0).save(path)
    back = load_scenario(path).overlay(env.sim.layout, env.sim.layout.default_q, task_id=env.task_id)
    robot = env.sim.layout.robot_coords
    assert np.abs(back[:robot] - q[:robot]).max() < 1e-3
    c = env.sim.layout.entity_coord[env.task.entities["bar"].slot]
    assert np.abs(back[c : c + 3] - q[c : c + 3]).max() < 1e-3
    # the option path: an env started from the saved scenario resets to it
    env2 = make_env("GalbotG1-PickToShelf-Nav-v0", num_envs=1, device="cpu", task_options={"init_scenario": str(path)})
    q2 = wp.to_torch(env2.state.joint_q).view(1, -1)[0].numpy()
    assert np.abs(q2[:robot] - q[:robot]).max() < 1e-3


@pytest.mark.parametrize(
    "doc, match",
    [
        ({"schema": "other"}, "schema must be"),
        ({"schema": "newton_lab/scenario-v1", "colour": 1}, r"unknown field\(s\) \['colour'\]"),
        ({"schema": "newton_lab/scenario-v1", "articulations": {"robot": {"base_pose": [0, 0, 0]}}}, "7 numbers"),
        ({"schema": "newton_lab/scenario-v1", "articulations": {"robot": {"velocity": {}}}}, "unknown field"),
        ({"schema": "newton_lab/scenario-v1", "articulations": {"arm2": {}}}, r"\['arm2'\]"),
        ({"schema": "newton_lab/scenario-v1", "rigid_objects": {"bar": {"root_pose": [0] * 7}}}, "non-zero quaternion"),
    ],
)
def test_bad_scenario_documents(doc, match):
    from newton_lab.envs.scenario import ScenarioError, parse_scenario

    with pytest.raises(ScenarioError, match=match):
        parse_scenario(doc, "bad.yaml")


def test_scenario_names_unknown_joint_and_object(shelf_env, tmp_path):
    from newton_lab.envs.scenario import ScenarioError, parse_scenario

    lay = shelf_env.sim.layout
    doc = {"schema": "newton_lab/scenario-v1", "articulations": {"robot": {"joint_position": {"elbow": 1.0}}}}
    with pytest.raises(ScenarioError, match="unknown joint 'elbow'"):
        parse_scenario(doc, "s.yaml").overlay(lay, lay.default_q, task_id=COHERENT)
    doc = {"schema": "newton_lab/scenario-v1", "rigid_objects": {"mug": {"root_pose": [0, 0, 0, 0, 0, 0, 1]}}}
    with pytest.raises(ScenarioError, match="rigid_objects.mug is not an object.*valid objects"):
        parse_scenario(doc, "s.yaml").overlay(lay, lay.default_q, task_id=COHERENT)
    doc = {"schema": "newton_lab/scenario-v1", "rigid_objects": {"table": {"root_pose": [5, 0, 0, 0, 0, 0, 1]}}}
    with pytest.raises(ScenarioError, match="static object"):
        parse_scenario(doc, "s.yaml").overlay(lay, lay.default_q, task_id=COHERENT)


def test_bad_scenario_file_and_option(tmp_path):
    from newton_lab.envs import make_env
    from newton_lab.envs.scenario import ScenarioError, load_scenario

    with pytest.raises(ScenarioError, match="does not exist"):
        load_scenario(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("schema: [unclosed\n")
    with pytest.raises(ScenarioError, match="not valid YAML"):
        load_scenario(bad)
    with pytest.raises(ValueError, match=r"unknown task option\(s\) \['sorting_object'\].*init_scenario"):
        make_env("GalbotG1-PickToShelf-Nav-v0", task_options={"sorting_object": "red_cube"})


# ---------------------------------------------------------------- SortToShelf
def test_sort_to_shelf_options_and_layout():
    from newton_lab.envs import make_env
    from newton_lab.task_api.registry import lookup

    with pytest.raises(ValueError, match=r"unknown sorting_object 'mug'; valid values: \['red_cube', 'blue_cuboid'"):
        make_env("GalbotG1-SortToShelf-v0", task_options={"sorting_object": "mug"})
    with pytest.raises(ValueError, match=r"unknown task option\(s\) \['colour'\]"):
        make_env("GalbotG1-SortToShelf-Pick-v0", task_options={"colour": "red"})
    cfg = lookup("GalbotG1-SortToShelf-v0").cfg(sorting_object="yellow_cylinder")
    assert [t.name for t in cfg.actions] == ["base_action", "leg_action", "arm_action", "gripper_action"]
    assert sum(len(spec.JOINT_GROUPS[t.group]) for t in cfg.actions) == 17
    assert cfg.actions[0].clip is None, "the coherent task's wheels are not clipped"
    assert [p.fixed_base for p in cfg.phases] == [True, False, False]
    nav = lookup("GalbotG1-SortToShelf-Nav-v0").cfg(sorting_object="blue_cuboid")
    assert nav.scenario.endswith("nav_blue_cuboid.yaml") and nav.actions[0].clip == (-4.5, 4.5)


@pytest.mark.slow
def test_sort_to_shelf_upper_row_with_leg_lift():
    """Coherent SortToShelf for the red cube (upper cell): the legs lift during nav and the cube ends in a1."""
    from newton_lab.tasks.sort_to_shelf.objects import OBJECTS

    from newton_lab.agents import expert_agent
    from newton_lab.envs import make_env

    env = make_env(
        "GalbotG1-SortToShelf-v0",
        num_envs=1,
        device="cpu",
        seed=2,
        randomize=True,
        task_options={"sorting_object": "red_cube"},
    )
    agent = expert_agent(env)
    env.reset()
    lift_in_place = []
    for _ in range(700):
        phase = int(env.info["phase"][0])
        _, _, term, trunc, info = env.step(agent.act(env))
        if bool(term[0] | trunc[0]):
            break
        if phase == 2:
            lift_in_place.append(float(env.joints.positions(["leg_joint1"])[0, 0]))
    assert bool(info["success"][0]), env.task.termination_reasons[int(info["termination_reason"][0])]
    assert min(lift_in_place) > 0.15, "legs lifted for the upper row while placing"
    final = env.buffers.terminal_joint_q[0].numpy()
    c = env.sim.layout.entity_coord[env.task.entities["red_cube"].slot]
    assert np.linalg.norm(final[c : c + 2] - np.asarray(OBJECTS["red_cube"].target[:2])) < 0.10
