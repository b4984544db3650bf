"""SortToShelf-All: four objects, fifteen phases, one episode (real physics on CPU Warp, 1-2 worlds).

The layout and the per-episode order, the target one-hot that conditions a phase policy (and survives
``obs_mode="sensors"``), the expert sorting all four objects, the split into phase datasets, and a composed
evaluation with stand-in phase policies."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from newton_lab.envs import make_env
from newton_lab.task_api.registry import lookup

TASK = "GalbotG1-SortToShelf-All-v0"
OBJECTS = ("red_cube", "blue_cuboid", "yellow_cylinder", "green_cylinder")
PHASES = [f"{k}_{i}" for i in range(1, 5) for k in ("pick", "nav", "place", "return")][:-1]


@pytest.fixture(scope="module")
def env():
    return make_env(TASK, num_envs=2, device="cpu", seed=3, randomize=True, cameras=False)


@pytest.fixture(scope="module")
def expert_run(env, tmp_path_factory):
    """One expert episode per row, recorded (the split's source)."""
    from newton_lab.agents import expert_agent

    path = tmp_path_factory.mktemp("sort_all") / "demos.hdf5"
    ref = env.collect(agent=expert_agent(env), episodes=2, path=path, max_steps=3000, progress=False)
    return SimpleNamespace(ref=ref)


def _order(env, row: int) -> list[int]:
    return [int(v) for v in env.info["command"][row].tolist()]


def test_layout_options_and_sensor_observation():
    cfg = lookup(TASK).make_cfg({})
    assert cfg.phase_names == PHASES
    assert [p.kind for p in cfg.phases] == [name.split("_")[0] for name in PHASES]
    by_kind = {p.kind: p.task_id for p in cfg.phases}
    assert by_kind == {
        "pick": "GalbotG1-SortToShelf-Pick-v0",
        "nav": "GalbotG1-SortToShelf-Nav-v0",
        "place": "GalbotG1-SortToShelf-Place-v0",
        "return": "GalbotG1-SortToShelf-Return-v0",
    }
    assert {p.target_option for p in cfg.phases if p.kind != "return"} == {"sorting_object"}
    assert [p.fixed_base for p in cfg.phases] == [p.kind == "pick" for p in cfg.phases]
    assert [t.name for t in cfg.actions] == ["base_action", "leg_action", "arm_action", "gripper_action"]
    sensors = lookup(TASK).make_cfg({"obs_mode": "sensors"})
    assert "sorting_object" in sensors.observations, "the target one-hot is the instruction, not a pose"
    assert not any(t.privileged for t in sensors.observations.values())
    assert "object_pose" in cfg.observations and "object_pose" not in sensors.observations
    with pytest.raises(ValueError, match=r"unknown task option\(s\) \['sorting_object'\]"):
        lookup(TASK).make_cfg({"sorting_object": "red_cube"})


def test_order_is_a_permutation_drawn_per_episode(env):
    orders = set()
    for _ in range(3):
        env.reset()
        for row in range(env.num_envs):
            order = _order(env, row)
            assert sorted(order) == [0, 1, 2, 3]
            orders.add(tuple(order))
    assert len(orders) >= 3, f"the order is drawn per row and episode; saw only {orders}"
    fixed = make_env(TASK, num_envs=1, device="cpu", cameras=False)
    fixed.reset()
    assert _order(fixed, 0) == [0, 1, 2, 3], "without randomisation the objects are sorted in OBJECTS order"


def test_target_one_hot_follows_the_phase(env):
    env.reset()
    hot = env.task.obs_terms["sorting_object"]
    order = _order(env, 0)
    assert int(env.obs[0, hot].argmax()) == order[0] and float(env.obs[0, hot].sum()) == 1.0
    for phase, position in ((4, 1), (11, 2), (14, 3)):  # pick_2, return_3 (still the third object), place_4
        env.info["phase"][0] = phase
        env.step(env.current_action())
        assert int(env.info["phase"][0]) == phase
        assert int(env.obs[0, hot].argmax()) == order[position], f"phase {PHASES[phase]}"


def test_the_target_switch_refuses_in_one_line(env):
    from newton_lab.agents import TargetSwitchAgent, ZeroAgent

    with pytest.raises(ValueError, match=r"PickToShelf-Pick-v0 has no option 'sorting_object' with choices"):
        TargetSwitchAgent.of_component("GalbotG1-PickToShelf-Pick-v0", "sorting_object")
    switch = TargetSwitchAgent("colour", {"red": ZeroAgent(), "blue": ZeroAgent()})
    with pytest.raises(ValueError, match=r"needs an observation term 'colour' of 2 columns \(the one-hot of"):
        switch.act(env)


def test_expert_sorts_all_four_objects_in_the_drawn_order(expert_run):
    from newton_lab.tasks.sort_to_shelf.objects import OBJECTS as SPEC

    from newton_lab.datasets import list_demos, read_dataset_info, read_episode

    ref = expert_run.ref
    assert ref["episodes"] == 2 and ref["success_rate"] == 1.0, ref.metadata
    info, orders = read_dataset_info(ref.path), []
    for demo in list_demos(ref.path):
        assert info["demos"][demo]["success"]
        ep = read_episode(ref.path, demo)
        phase = ep["datagen"]["phase"].reshape(-1)
        assert np.array_equal(np.unique(phase), np.arange(len(PHASES)))
        assert np.all(np.diff(phase) >= 0), "phases advance in order, none skipped"
        hot = ep["obs"]["sorting_object"]
        order = [OBJECTS[int(hot[np.argmax(phase == 4 * k)].argmax())] for k in range(4)]  # at each pick's start
        assert sorted(order) == sorted(OBJECTS)
        signals = ep["datagen"]["subtask_signals"]
        first_sorted = {name: int(np.argmax(signals[f"sorted_{name}"] > 0.5)) for name in OBJECTS}
        first_picked = {name: int(np.argmax(signals[f"picked_{name}"] > 0.5)) for name in OBJECTS}
        assert sorted(OBJECTS, key=first_picked.get) == order, "each object is picked in the drawn order"
        assert all(signals[f"sorted_{name}"].any() for name in OBJECTS)
        assert sorted(OBJECTS, key=first_sorted.get) == order, "each object lands in its cell in the drawn order"
        r, n = ep["rewards"], len(PHASES)  # (phase + r_phase) / 15; a step that ends phase p is rewarded in p + 1
        assert np.isfinite(r).all() and r.min() >= 0.0 and r[-1] == pytest.approx(1.0, abs=1e-5)
        for p in range(n):
            assert p / n - 1e-5 <= r[phase == p].min() <= r[phase == p].max() <= (p + 2) / n + 1e-5, PHASES[p]
        for name in OBJECTS:
            xy = ep["datagen"]["object_poses"][name][-1, :2]
            assert np.linalg.norm(xy - np.asarray(SPEC[name].target[:2])) < 0.10, f"{name} ends in its cell"
        orders.append(order)
    assert orders[0] != orders[1], "the two rows sort in different orders (seed 3)"


def test_split_writes_one_dataset_per_phase_kind(expert_run, tmp_path):
    from newton_lab.datasets import list_demos, read_dataset_info, read_episode
    from newton_lab.datasets.split import split_by_phase

    parts = split_by_phase(expert_run.ref.path, tmp_path / "phases", workers=1)
    assert list(parts) == ["pick", "nav", "place", "return"]
    for kind, ref in parts.items():
        info = read_dataset_info(ref.path)
        assert info["task_id"] == f"GalbotG1-SortToShelf-{kind.capitalize()}-v0"
        demos = list_demos(ref.path)
        assert len(demos) == (6 if kind == "return" else 8), "a segment per phase of the kind, per episode"
        assert all(info["demos"][d]["success"] for d in demos), kind
        assert ref.metadata["episodes"] == len(demos)
    pick = [read_episode(parts["pick"].path, d) for d in list_demos(parts["pick"].path)]
    assert [str(ep["attrs"]["phase"]) for ep in pick[:4]] == ["pick_1", "pick_2", "pick_3", "pick_4"]
    assert all(ep["actions"].shape[1] == 8 for ep in pick)  # arm + gripper
    targets = [int(ep["obs"]["sorting_object"][0].argmax()) for ep in pick[:4]]
    assert sorted(targets) == [0, 1, 2, 3], "one episode's four picks are of its four objects"
    assert read_episode(parts["return"].path, 0)["actions"].shape[1] == 16  # wheels, legs, arm
    only = split_by_phase(expert_run.ref.path, tmp_path / "only", phases=["place"], workers=1)
    assert list(only) == ["place"]
    with pytest.raises(
        ValueError, match=r"has no phase 'pick_1' \(did you mean pick\?\); its phases: pick, nav, place, return"
    ):
        split_by_phase(expert_run.ref.path, tmp_path / "none", phases=["pick_1"])


def test_split_by_target_writes_one_dataset_per_object(expert_run, tmp_path):
    from newton_lab.datasets import list_demos, read_dataset_info, read_episode
    from newton_lab.datasets.split import split_by_phase

    parts = split_by_phase(expert_run.ref.path, tmp_path / "t", phases=["pick", "place"], by_target=["pick"], workers=1)
    assert list(parts) == [f"pick/{o}" for o in OBJECTS] + ["place"]
    for i, name in enumerate(OBJECTS):
        ref = parts[f"pick/{name}"]
        assert ref.path.name == f"pick-{name}.hdf5"
        info = read_dataset_info(ref.path)
        assert info["task_id"] == "GalbotG1-SortToShelf-Pick-v0"
        assert info["env_args"]["env_kwargs"]["task_options"]["sorting_object"] == name, "recorded for its object"
        demos = list_demos(ref.path)
        assert len(demos) == 2, "each episode picks every object once"
        for d in demos:
            ep = read_episode(ref.path, d)
            assert (ep["obs"]["sorting_object"].argmax(axis=1) == i).all() and info["demos"][d]["success"]
            assert ep["actions"].shape[1] == 8
    assert len(list_demos(parts["place"].path)) == 8, "the kinds not split by target stay whole"
    with pytest.raises(ValueError, match=r"phase kind 'return' of .* acts on no per-row target, .* kinds with one: "):
        split_by_phase(expert_run.ref.path, tmp_path / "r", by_target=["return"])
    with pytest.raises(ValueError, match=r"has no phase 'lift'"):
        split_by_phase(expert_run.ref.path, tmp_path / "l", by_target=["lift"])


@pytest.fixture(scope="module")
def phase_policies(expert_run, tmp_path_factory):
    """A tiny state policy per learned kind (pick, place), trained a few steps on the split demos, conditioned on
    the target one-hot; the flow's learned kinds and its training inputs."""
    from newton_lab.flows.settings import learned_kinds, with_inputs

    from newton_lab.datasets.split import split_by_phase
    from newton_lab.policies import Policy

    root = tmp_path_factory.mktemp("sort_all_policies")
    parts = split_by_phase(expert_run.ref.path, root / "phases", workers=1)
    cfg = lookup(TASK).make_cfg({"obs_mode": "sensors"})
    base = {"obs_keys": ["robot_joint_pos", "gripper_pos"], "down_dims": (16, 32, 64), "diffusion_step_embed_dim": 32}
    train = with_inputs({**base, "max_steps": 3, "batch_size": 8, "progress": False}, cfg.target_observations)
    assert train["obs_keys"] == ["robot_joint_pos", "gripper_pos", "sorting_object"]
    return {
        kind: Policy.from_backend("diffusion").train(parts[kind], {**train, "output_dir": str(root / kind)})
        for kind in learned_kinds(cfg)
    }


def test_composed_evaluation_with_one_policy_per_kind(phase_policies):
    from newton_lab.policies.agent import phase_policy_agent

    assert list(phase_policies) == ["pick", "place"]
    env = make_env(
        TASK, num_envs=2, device="cpu", seed=5, randomize=True, cameras=False, task_options={"obs_mode": "sensors"}
    )
    agent = phase_policy_agent(env, {k: str(v) for k, v in phase_policies.items()})
    picks = {id(agent.phase_agents[i]) for i, name in enumerate(PHASES) if name.startswith("pick")}
    assert len(picks) == 1, "one pick policy runs pick_1 .. pick_4"
    assert "sorting_object" in agent.phase_agents[0].policy.obs_keys
    summary = env.evaluate(agent=agent, episodes=2, max_steps=40, progress=False)
    phases = summary["phases"]
    assert list(phases) == PHASES and summary["episodes"] == 2
    assert phases["pick_1"]["reached"] == 2 and phases["pick_1"]["passed"] == 0, "3 training steps lift nothing"
    assert sum(phases["pick_1"]["stalled"].values()) == 2
    assert set(phases["pick_1"]["stalled"]) <= {"max_steps", "object_tipped", "object_dropped"}
    assert set(summary["subtask_signals"]) >= {f"{s}_{o}" for o in OBJECTS for s in ("picked", "sorted")}
    with pytest.raises(ValueError, match=r"has no phase 'lift'; its phases: pick, nav, place, return"):
        phase_policy_agent(env, {"lift": str(phase_policies["pick"])})


@pytest.fixture(scope="module")
def pick_per_object(expert_run, tmp_path_factory):
    """A tiny state pick policy per object, trained a few steps on that object's pick segments (the flow's
    per-target trainings: no target input)."""
    from newton_lab.flows.settings import phase_trainings

    from newton_lab.datasets.split import split_by_phase
    from newton_lab.policies import Policy

    root = tmp_path_factory.mktemp("sort_all_per_object")
    parts = split_by_phase(expert_run.ref.path, root / "phases", phases=["pick"], by_target=["pick"], workers=1)
    cfg = lookup(TASK).make_cfg({"obs_mode": "sensors"})
    base = {"obs_keys": ["robot_joint_pos", "gripper_pos"], "down_dims": (16, 32, 64), "diffusion_step_embed_dim": 32}
    trainings = phase_trainings(cfg, {**base, "max_steps": 3, "batch_size": 8, "progress": False}, ["pick"])
    assert list(trainings) == [f"pick/{o}" for o in OBJECTS] + ["place"]
    assert trainings["place"]["obs_keys"][-1] == "sorting_object", "the place policy stays conditioned"
    return {
        name: Policy.from_backend("diffusion").train(parts[name], {**train, "output_dir": str(root / name)})
        for name, train in trainings.items()
        if name.startswith("pick/")
    }


def test_composed_evaluation_with_one_pick_policy_per_object(pick_per_object, phase_policies):
    from newton_lab.agents import TargetSwitchAgent
    from newton_lab.policies.agent import PolicyAgent, phase_policy_agent

    env = make_env(
        TASK, num_envs=2, device="cpu", seed=8, randomize=True, cameras=False, task_options={"obs_mode": "sensors"}
    )
    named = {**{k: str(v) for k, v in pick_per_object.items()}, "place": str(phase_policies["place"])}
    agent = phase_policy_agent(env, named)
    switch = agent.phase_agents[0]
    assert isinstance(switch, TargetSwitchAgent) and list(switch.agents) == list(OBJECTS)
    assert all(agent.phase_agents[4 * k] is switch for k in range(4)), "one switch runs pick_1 .. pick_4"
    assert all(isinstance(a, PolicyAgent) and "sorting_object" not in a.policy.obs_keys for a in switch.agents.values())
    env.reset()
    agent.act(env)
    first = [int(env.obs[r, env.task.obs_terms["sorting_object"]].argmax()) for r in range(2)]
    assert first[0] != first[1], "seed 8 starts the rows on different objects"
    for i, sub in enumerate(switch.agents.values()):  # a row's action comes from its own object's policy alone
        planned = set(np.nonzero(sub._cursor == 1)[0].tolist())
        assert planned == {r for r in range(2) if first[r] == i}, OBJECTS[i]
    seen: list[list[str]] = []  # each row's target at every step (its first episode's at the first step)
    hot = env.task.obs_terms["sorting_object"]
    on_step = lambda *_: seen.append([OBJECTS[int(v)] for v in env.obs[:, hot].argmax(dim=1)])  # noqa: E731
    summary = env.evaluate(agent=agent, episodes=2, max_steps=40, progress=False, on_step=on_step)
    assert summary["phases"]["pick_1"]["reached"] == 2 and summary["phases"]["pick_1"]["passed"] == 0
    expected: dict[str, dict[str, int]] = {}
    for name in seen[0]:  # per object, the picks that episodes reached and passed
        expected.setdefault(name, {"reached": 0, "passed": 0})["reached"] += 1
    assert summary["phase_targets"] == {"pick": expected}
    for bad, match in (
        ({k: v for k, v in named.items() if k != "pick/green_cylinder"}, r"one policy per target .* missing: green_"),
        ({**named, "pick/purple_cone": named["place"]}, r"phase kind 'pick' has no target 'purple_cone'; its targ"),
        ({**named, "pick": named["place"]}, r"'pick' was given both ways"),
        ({"return/red_cube": named["place"]}, r"phase kind 'return' of .* acts on no per-row target"),
    ):
        with pytest.raises(ValueError, match=match):
            phase_policy_agent(env, bad)


def test_the_phase_table_per_object_counts_each_kind_on_each_target():
    from newton_lab.envs.rollout import phase_target_summary

    cfg = lookup(TASK).make_cfg({})
    order = {"pick_1": "red_cube", "nav_1": "red_cube", "place_1": "red_cube", "pick_2": "green_cylinder"}
    records = [
        {"phase": "pick_2", "success": False, "targets": order},  # sorted the red cube, stalled picking the cylinder
        {"phase": "place_1", "success": False, "targets": {k: order[k] for k in ("pick_1", "nav_1", "place_1")}},
        {"phase": "pick_1", "success": False, "targets": {"pick_1": "blue_cuboid"}},
    ]
    table = phase_target_summary(cfg, records)
    assert table == {
        "pick": {
            "red_cube": {"reached": 2, "passed": 2},
            "green_cylinder": {"reached": 1, "passed": 0},
            "blue_cuboid": {"reached": 1, "passed": 0},
        },
        "nav": {"red_cube": {"reached": 2, "passed": 2}},
        "place": {"red_cube": {"reached": 2, "passed": 1}},
    }
    won = {"phase": "place_4", "success": True, "targets": {"place_4": "red_cube"}}
    assert phase_target_summary(cfg, [won]) == {"place": {"red_cube": {"reached": 1, "passed": 1}}}


def test_the_gpu_pipeline_plan_and_its_suite_row(capsys):
    import json

    from newton_lab.flows.suite_rows import rows_of

    from newton_lab.cli import main

    assert main(["pipeline", "--task", TASK, "--recipe", "gpu", "--dry-run"]) == 0
    plan = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["plan"]
    assert plan["long_horizon"] and plan["per_target"] == ["pick"]
    assert plan["learned_phases"] == [f"pick/{o}" for o in OBJECTS] + ["place"], "a pick policy per object"
    assert plan["demos"] == 600 and plan["eval_max_steps"] == 5000 and plan["train_cfg"]["time_budget_s"] == 600
    keys = plan["train_cfg"]["obs_keys"]
    assert keys[-1] == "sorting_object" and not any("pose" in k for k in keys), "the one-hot, and no object pose"
    assert plan["train_cfg"]["instruction_keys"] == ["sorting_object"], "the one-hot conditions the image trunks"
    assert main(["pipeline", "--task", TASK, "--recipe", "gpu", "--per-target", "none", "--dry-run"]) == 0
    plan = json.loads(capsys.readouterr().out.strip().splitlines()[-1])["plan"]
    assert plan["learned_phases"] == ["pick", "place"] and "per_target" not in plan
    assert main(["pipeline", "--task", TASK, "--recipe", "gpu", "--per-target", "nav", "--dry-run"]) == 2
    assert "per-target policies for 'nav': GalbotG1-SortToShelf-All-v0 learns the phase kinds pick, place" in (
        capsys.readouterr().err
    )
    (row,) = rows_of("gpu", ["sorttoshelf-all"])
    assert row.is_pipeline and row.args[:3] == ("pipeline", "--task", TASK) and "gpu" in row.args
