"""Per-task physics settings (``TaskCfg.physics``): the defaults are the solver every task runs with, a contact
filter (``gripper_only()``, given through ``make_env(physics=...)``) reaches MuJoCo-Warp's collision and keeps the
contacts a task's success depends on, and a pair it declares non-colliding makes no contact (real Newton on CPU
Warp, 1-2 worlds)."""

from __future__ import annotations

import dataclasses

import newton
import numpy as np
import pytest

from newton_lab.agents import expert_agent
from newton_lab.envs import make_env
from newton_lab.envs.scene import check_contact_filter, task_posture
from newton_lab.robots.registry import robot_binding
from newton_lab.task_api.physics import ANY_OBJECT, GROUND, ContactFilterCfg, PhysicsCfg, gripper_only, merged
from newton_lab.task_api.registry import list_tasks, lookup

PICK = "GalbotG1-PickCube-v0"
TASKS = (PICK, "GalbotG1-StackCube-v0", "GalbotG1-PickToShelf-v0", "GalbotG1-SortToShelf-v0")


def filtered(task_id: str, iterations: int | None = None) -> PhysicsCfg:
    """The task's physics with ``gripper_only()`` (and ``iterations``, when given)."""
    own = lookup(task_id).make_cfg({}).physics
    return dataclasses.replace(own, contact_filter=gripper_only(), iterations=iterations or own.iterations)


LINK = "left_arm_link3"
"""A left-arm link (upper arm capsule): PickCube's filter lets only the left gripper touch anything."""


def test_default_physics_is_the_solver_every_task_ran_with():
    options = PhysicsCfg().solver_options()
    assert options == dict(
        use_mujoco_cpu=False,
        solver="newton",
        integrator="implicitfast",
        cone="elliptic",
        iterations=20,
        ls_iterations=10,
        tolerance=None,
        ls_tolerance=None,
        impratio=10.0,
        nconmax=None,
        njmax=None,
    )
    with pytest.raises(ValueError, match="cone"):
        PhysicsCfg(cone="round")


def test_every_task_declares_a_valid_physics():
    for task_id in list_tasks():
        cfg = lookup(task_id).make_cfg({})
        assert isinstance(cfg.physics, PhysicsCfg), task_id
        if cfg.physics.contact_filter is not None:
            check_contact_filter(cfg, robot_binding(cfg.robot), cfg.physics.contact_filter)
    for task_id in TASKS:  # gripper_only() names only what these scenes and the robot have
        cfg = lookup(task_id).make_cfg({})
        check_contact_filter(cfg, robot_binding(cfg.robot), gripper_only())


def test_a_filter_naming_what_the_scene_lacks_is_refused():
    cfg = lookup(PICK).make_cfg({})
    g1 = robot_binding(cfg.robot)
    with pytest.raises(ValueError, match="robot group 'left_hand'"):
        check_contact_filter(cfg, g1, ContactFilterCfg(robot={"left_hand": (ANY_OBJECT,)}))
    with pytest.raises(ValueError, match="shelf"):
        check_contact_filter(cfg, g1, ContactFilterCfg(robot={"left_gripper": ("cube", "shelf")}))


def test_a_coherent_task_runs_what_every_phase_needs():
    a = PhysicsCfg(
        iterations=5,
        ls_iterations=5,
        constraints_per_world=128,
        contact_filter=ContactFilterCfg(robot={"left_gripper": ("cube",)}),
    )
    b = PhysicsCfg(
        iterations=8,
        ls_iterations=4,
        contact_filter=ContactFilterCfg(robot={"left_gripper": (GROUND,), "left_arm": ("table",)}),
    )
    m = merged([a, b])
    assert (m.iterations, m.ls_iterations, m.constraints_per_world, m.contacts_per_world) == (8, 5, 128, None)
    assert m.contact_filter.robot == {"left_gripper": ("cube", GROUND), "left_arm": ("table",)}
    assert merged([a, PhysicsCfg()]).contact_filter is None  # a phase without a filter: none
    coherent = lookup("GalbotG1-PickToShelf-v0").make_cfg({}).physics
    assert coherent == lookup("GalbotG1-PickToShelf-Pick-v0").make_cfg({}).physics


def _geom_pairs(env) -> set[tuple[str, str]]:
    """Label pairs (last path part) of MuJoCo-Warp's broad-phase candidate geom pairs of world 0."""
    solver, model = env.solver, env.model
    shape = solver.mjc_geom_to_newton_shape.numpy()[0]
    label = [model.shape_label[s].rsplit("/", 1)[-1] if s >= 0 else "?" for s in shape]
    pairs = solver.mjw_model.nxn_geom_pair_filtered.numpy()
    return {tuple(sorted((label[int(a)], label[int(b)]))) for a, b in (p for p in pairs)}


GRIPPER = {"left_palm", "left_gripper_l_finger_link_geom_0", "left_gripper_r_finger_link_geom_0"}
"""The left gripper's collision geoms (labels), the only robot geoms ``gripper_only()`` lets touch anything."""


def test_the_filter_reaches_mujoco_warps_broad_phase():
    before = make_env(
        PICK,
        num_envs=1,
        device="cpu",
        capture=False,
        cameras=False,
        physics=PhysicsCfg(constraints_per_world=128, weld_idle_joints=False),
    )
    task = make_env(PICK, num_envs=2, device="cpu", capture=False, cameras=False, physics=filtered(PICK, 5))
    assert task.solver.mj_model.opt.iterations == task.cfg.physics.iterations == 5
    assert before.solver.mj_model.opt.iterations == 20
    old = _geom_pairs(before)
    assert len(old) == 75  # 18 robot geoms x (table, cube, block, ground) + the cube's 3
    assert ("cube", LINK + "_geom_0") in old
    assert _geom_pairs(task) == _gripper_only_pairs(task)


@pytest.mark.parametrize("task_id", ["GalbotG1-StackCube-v0", "GalbotG1-PickToShelf-v0", "GalbotG1-SortToShelf-v0"])
def test_every_filtered_task_leaves_mujoco_exactly_the_gripper_and_object_pairs(task_id):
    env = make_env(task_id, num_envs=1, device="cpu", capture=False, cameras=False, physics=filtered(task_id))
    assert _geom_pairs(env) == _gripper_only_pairs(env)


def _gripper_only_pairs(env) -> set[tuple[str, str]]:
    """What ``gripper_only()`` leaves: the gripper against every object, every dynamic object against every other
    object and the ground (static objects never collide with each other)."""
    objects = [e.name for e in env.cfg.entities]
    pairs = {tuple(sorted((g, o))) for g in GRIPPER for o in objects}
    dynamic = [e.name for e in env.cfg.entities if e.dynamic]
    return pairs | {tuple(sorted((d, o))) for d in dynamic for o in [*objects, "ground_plane"] if o != d}


def _contacts_of(env, body_a: int, body_b: int) -> int:
    """Contacts of world 0 between the bodies ``body_a`` and ``body_b`` after the last physics step."""
    d, solver, model = env.solver.mjw_data, env.solver, env.model
    n = int(d.nacon.numpy()[0])
    geom, world = d.contact.geom.numpy()[:n], d.contact.worldid.numpy()[:n]
    shape = solver.mjc_geom_to_newton_shape.numpy()
    shape_body = model.shape_body.numpy()
    bodies = {(int(shape_body[shape[w, a]]), int(shape_body[shape[w, b]])) for (a, b), w in zip(geom, world) if w == 0}
    return sum(pair in bodies for pair in ((body_a, body_b), (body_b, body_a)))


@pytest.mark.parametrize("physics", ["filtered", "task"])
def test_a_declared_non_colliding_pair_makes_no_contact(physics):
    """The cube placed inside a left-arm link: with ``gripper_only()`` nothing touches it (it falls freely); with
    PickCube's own physics (no filter) the link makes contacts and pushes it out."""
    env = make_env(
        PICK,
        num_envs=1,
        device="cpu",
        capture=False,
        cameras=False,
        physics=filtered(PICK) if physics == "filtered" else None,
    )
    labels = env.model.body_label
    link = next(i for i, name in enumerate(labels) if name.endswith("/" + LINK))
    cube = env.task.entities["cube"]
    q = env.state.joint_q.numpy()
    link_pos = env.state.body_q.numpy()[link][:3]
    q[cube.coord : cube.coord + 7] = [*link_pos, 0.0, 0.0, 0.0, 1.0]
    env.state.joint_q.assign(q)
    env.state.joint_qd.zero_()
    newton.eval_fk(env.model, env.state.joint_q, env.state.joint_qd, env.state)
    env.sim.simulate()  # one control step of physics (5 substeps)
    moved = env.state.joint_q.numpy()[cube.coord : cube.coord + 3] - link_pos
    contacts = _contacts_of(env, link, cube.body)
    if physics == "filtered":
        assert contacts == 0
        assert np.abs(moved[:2]).max() < 1e-4  # no push sideways: it only falls
        assert -0.02 < moved[2] < 0.0  # 0.05 s of free fall: 1.2 cm
    else:
        assert contacts > 0
        assert np.abs(moved[:2]).max() > 2e-3  # pushed out sideways


@pytest.mark.parametrize("task_id", TASKS)
def test_the_filter_keeps_the_contacts_grasp_and_place_need(task_id):
    """The expert grasps and places with ``gripper_only()`` and the fewest iterations its solves needed (PickCube:
    cube released on the block; StackCube: both cubes stacked and released; the shelf tasks: picked, carried to
    the shelf, placed)."""
    n = 2 if task_id == PICK else 1
    fewest = {PICK: 5, "GalbotG1-StackCube-v0": 8, "GalbotG1-PickToShelf-v0": 5, "GalbotG1-SortToShelf-v0": 8}
    env = make_env(
        task_id,
        num_envs=n,
        device="cpu",
        seed=100,
        randomize=True,
        cameras=False,
        physics=filtered(task_id, fewest[task_id]),
    )
    assert env.cfg.physics.contact_filter == gripper_only()
    summary = env.evaluate(agent=expert_agent(env), episodes=n, max_steps=1500, progress=False)
    assert summary["success_rate"] == 1.0, summary


def _probe():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "tools" / "frozen_dof_probe.py"  # tools/ is no package
    spec = importlib.util.spec_from_file_location("frozen_dof_probe", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_welding_joints_at_the_posture_keeps_every_body_where_the_posture_puts_it():
    """tools/frozen_dof_probe.py's welded G1 (only the left arm and gripper free): 16 DoF per world instead of 40,
    every body at the pose forward kinematics gives the full robot in the task's posture, and no actuator or
    equality left naming a welded joint."""
    import xml.etree.ElementTree as ET

    probe = _probe()
    cfg = lookup(PICK).make_cfg({})
    mjcf = probe.welded_mjcf(task_posture(cfg, robot_binding(cfg.robot)), probe.MOVING)
    root = ET.fromstring(mjcf)
    assert sorted(j.get("name") for j in root.find("worldbody").iter("joint")) == sorted(probe.MOVING)
    named = {
        v
        for e in [*root.iter("position"), *root.iter("velocity"), *root.find("equality")]
        for k, v in e.attrib.items()
        if k in ("joint", "joint1", "joint2")
    }
    assert named <= set(probe.MOVING)
    poses = {}
    for name, text in (("full", None), ("welded", mjcf)):
        model = probe.build(cfg, 1, "cpu", text)
        state = model.state()
        newton.eval_fk(model, state.joint_q, state.joint_qd, state)
        labels = [label.rsplit("/", 1)[-1] for label in model.body_label]
        poses[name] = ({labels[i]: q for i, q in enumerate(state.body_q.numpy())}, model.joint_dof_count)
    (full, full_dofs), (welded, welded_dofs) = poses["full"], poses["welded"]
    assert (full_dofs, welded_dofs) == (40, 16)
    for body in ("left_arm_link7", "right_arm_link7", "head_link2", "left_gripper_l_finger_link", "cube"):
        np.testing.assert_allclose(welded[body][:3], full[body][:3], atol=1e-5, err_msg=body)
        assert abs(abs(float(np.dot(welded[body][3:], full[body][3:]))) - 1.0) < 1e-5, body


def _weld(task_id: str, on: bool) -> PhysicsCfg:
    return dataclasses.replace(lookup(task_id).make_cfg({}).physics, weld_idle_joints=on)


def test_welding_idle_joints_keeps_the_full_robot_layout_and_the_expert_episodes():
    """``PhysicsCfg(weld_idle_joints=True)`` on PickCube: the solver steps the left arm, the gripper (its fingers
    follow it) and the cube, 17 coordinates a world instead of 41; the env's coordinates, observations and actions
    keep the full robot's layout, a welded joint reads its posture and zero velocity while the arm works, and the
    expert's episodes succeed as without welding (same lengths, TCP within a few mm mid-episode)."""
    import torch
    import warp as wp

    envs = {
        on: make_env(PICK, num_envs=2, device="cpu", seed=100, randomize=True, cameras=False, physics=_weld(PICK, on))
        for on in (False, True)
    }
    full, welded = envs[False], envs[True]
    free = {
        *welded.robot.joint_groups["left_arm"],
        "left_gripper_joint",
        "left_gripper_l_finger_joint",
        "left_gripper_r_finger_joint",
    }
    assert set(welded.sim.layout.welded) == set(full.sim.layout.joints.coord) - free
    assert full.sim.joint_space is None and full.sim.layout.welded == ()
    assert welded.sim.joint_space.model.joint_coord_count // 2 == 17 and welded.sim.layout.coords_per_world == 41
    assert welded.obs.shape == full.obs.shape and welded.action_joint_names == full.action_joint_names
    idle = list(welded.sim.layout.welded)
    posture = welded.joints.positions(idle).clone()
    idle_dofs = [welded.sim.layout.joints.dof[n] for n in idle]
    agents = {on: expert_agent(env) for on, env in envs.items()}
    for _ in range(60):
        for on, env in envs.items():
            env.step(agents[on].act(env))
    assert (full.buffers.tcp_pose[:, :3] - welded.buffers.tcp_pose[:, :3]).abs().max() < 0.005
    torch.testing.assert_close(welded.joints.positions(idle), posture)
    assert not wp.to_torch(welded.state.joint_qd).view(2, -1)[:, idle_dofs].any()
    moved = welded.joints.positions(list(welded.robot.joint_groups["left_arm"]))
    assert not torch.allclose(moved, full.joints.positions(list(full.robot.joint_groups["left_arm"])) * 0)
    runs = {
        on: env.evaluate(agent=expert_agent(env), episodes=4, max_steps=1500, progress=False)
        for on, env in envs.items()
    }
    assert runs[True]["success_rate"] == runs[False]["success_rate"] == 1.0, runs
    assert abs(runs[True]["average_length"] - runs[False]["average_length"]) <= 2.0, runs


def test_a_joint_coupled_to_a_free_one_stays_free_and_welding_refuses_unknown_joints():
    import xml.etree.ElementTree as ET

    from newton_lab.robots.g1 import spec
    from newton_lab.robots.g1.model import mjcf_path
    from newton_lab.robots.weld import weld_mjcf

    text, welded = weld_mjcf(mjcf_path(), {}, keep=["left_gripper_joint"])
    left = {j.get("name") for j in ET.fromstring(text).iter("joint") if j.get("name")}
    assert {"left_gripper_joint", "left_gripper_l_finger_joint", "left_gripper_r_finger_joint"} <= left
    assert "right_gripper_l_finger_joint" in welded and "head_joint1" in welded
    assert set(welded) | {"left_gripper_joint", "left_gripper_l_finger_joint", "left_gripper_r_finger_joint"} == set(
        spec.ALL_JOINT_NAMES
    )
    builder = newton.ModelBuilder()
    with pytest.raises(ValueError, match="no such joints"):
        robot_binding(lookup(PICK).make_cfg({}).robot).build(builder, {"nose_joint": 0.0})


def test_a_reset_that_moves_a_welded_joint_is_refused_in_one_line():
    """The env compares the first reset's coordinates of its welded joints with the values the solver welded them
    at: a reset that moved one (an event randomising the head, say) is refused, naming the joint and the fix."""
    from newton_lab.envs.drive import check_welded_reset

    env = make_env(PICK, num_envs=1, device="cpu", seed=0, cameras=False)
    names = list(env.sim.layout.welded)
    assert "head_joint2" in names
    reset = env.joints.positions(names).clone()
    check_welded_reset(PICK, env.sim.layout, reset, env.sim.layout.default_q)  # the task's own reset passes
    reset[0, names.index("head_joint2")] += 0.3
    with pytest.raises(ValueError, match="moves welded joint 'head_joint2'.*weld_idle_joints=False") as err:
        check_welded_reset(PICK, env.sim.layout, reset, env.sim.layout.default_q)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("task_id", [PICK, "GalbotG1-BaseNav-v0"])
def test_exchanging_the_state_once_a_control_step_steps_the_same_physics(task_id):
    """``PhysicsCfg(sync_every_substep=False)`` (the default): MuJoCo-Warp gets the coordinates before a control
    step's first substep and gives them back after its last (``envs.mujoco_substeps``), instead of Newton's push
    and pull around every substep. Over 60 expert steps every coordinate matches the per-substep exchange to
    float rounding, for PickCube's arm and for BaseNav's driven base, whose wheel twist turns with the yaw read
    from MuJoCo-Warp's ``qpos`` between substeps."""
    import torch
    import warp as wp

    def physics(sync: bool) -> PhysicsCfg:
        return dataclasses.replace(lookup(task_id).make_cfg({}).physics, sync_every_substep=sync)

    envs = {
        sync: make_env(
            task_id, num_envs=2, device="cpu", seed=100, randomize=True, cameras=False, physics=physics(sync)
        )
        for sync in (True, False)
    }
    assert (envs[False].sim.physics_exchange, envs[True].sim.physics_exchange) == ("control_step", "substep")
    agents = {sync: expert_agent(env) for sync, env in envs.items()}
    start = wp.to_torch(envs[False].state.joint_q).clone()
    for _ in range(60):
        for sync, env in envs.items():
            env.step(agents[sync].act(env))
        q = {sync: wp.to_torch(env.state.joint_q).clone() for sync, env in envs.items()}
        torch.testing.assert_close(q[False], q[True], atol=1e-5, rtol=0)
        torch.testing.assert_close(envs[False].buffers.tcp_pose, envs[True].buffers.tcp_pose, atol=1e-5, rtol=0)
    assert float((q[False] - start).abs().max()) > 0.05  # the arm or the base did move
