"""What the joints a table-top task never moves cost the solver: the task's bare solver step (its scene, entities,
physics and decimation, no env around it) with the full G1 against the same scene with every robot joint but the
moving ones welded at the task's posture, side by side in one process.

    python tools/frozen_dof_probe.py [--task GalbotG1-PickCube-v0] [--num-envs 4096] [--steps 200] [--device cuda:0]

Welding is done in the MJCF (``newton_lab.robots.weld``): a welded joint's element is removed and its posture value
is folded into its body's pose (MuJoCo rides a joint-less body on its parent), together with the actuators and
equality constraints that name it. The moving joints are the left arm and the left gripper (what PickCube,
StackCube and the shelf tasks' manipulation phases drive). This is the bare solver alone; a task welds its idle
joints inside the env with ``PhysicsCfg(weld_idle_joints=True)`` (``newton-lab bench`` then times it). It prints one
JSON line per variant (degrees of freedom per world, world-steps/s of the captured ``decimation`` solver steps) and
their ratio.
"""

from __future__ import annotations

import argparse
import json

import newton
import newton_lab.tasks  # noqa: F401  (registers every task id)
import warp as wp

from newton_lab.bench import _time_graph
from newton_lab.envs.scene import CONTACT_GAP, _add_entity, _replicate, task_posture
from newton_lab.robots.g1 import spec
from newton_lab.robots.g1.model import mjcf_path
from newton_lab.robots.registry import robot_binding
from newton_lab.robots.weld import weld_mjcf
from newton_lab.task_api.registry import lookup

MOVING = (*spec.LEFT_ARM_JOINTS, "left_gripper_joint", "left_gripper_l_finger_joint", "left_gripper_r_finger_joint")
"""Robot joints left free in the welded variant."""


def welded_mjcf(posture: dict[str, float], moving: tuple[str, ...]) -> str:
    """The G1 MJCF with every joint not in ``moving`` welded at its ``posture`` value (``robots.weld``)."""
    return weld_mjcf(mjcf_path(), posture, keep=moving)[0]


def build(cfg, num_envs: int, device, mjcf: str | None) -> newton.Model:
    """The task's scene replicated ``num_envs`` times, posture as drive targets: the robot as the env builds it
    (``mjcf`` None), or from the ``mjcf`` text (joints found by name)."""
    world = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(world)
    world.rigid_gap = CONTACT_GAP
    robot = robot_binding(cfg.robot)
    posture = task_posture(cfg, robot)
    if mjcf is None:
        coord = robot.build(world).coord
    else:
        world.add_mjcf(mjcf, enable_self_collisions=False, xform=wp.transform_identity())  # XML text
        coord = {label.rsplit("/", 1)[-1]: world.joint_q_start[j] for j, label in enumerate(world.joint_label)}
    for name, value in posture.items():
        if name in coord:
            world.joint_q[coord[name]] = value
            if name not in robot.base_planar_joints:
                world.joint_target_q[coord[name]] = value
    for e in cfg.entities:
        _add_entity(world, e)
    return _replicate(world, [], num_envs, device)


def measure(cfg, model: newton.Model, steps: int) -> dict:
    """World-steps/s of the captured ``cfg.decimation`` solver steps (one control step) on ``model``."""
    solver = newton.solvers.SolverMuJoCo(model, **cfg.physics.solver_options())
    solver.mjw_model.opt.warn_overflow = 0
    state, control = model.state(), model.control()
    newton.eval_fk(model, state.joint_q, state.joint_qd, state)
    with wp.ScopedDevice(model.device):
        for _ in range(cfg.decimation):  # compiles, settles
            solver.step(state, state, control, None, cfg.sim_dt)
        with wp.ScopedCapture(device=model.device) as cap:
            for _ in range(cfg.decimation):
                solver.step(state, state, control, None, cfg.sim_dt)
    t = _time_graph(lambda: wp.capture_launch(cap.graph), steps, model.device)
    return {"dofs_per_world": model.joint_dof_count // model.world_count, "env_steps_per_s": model.world_count / t}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", default="GalbotG1-PickCube-v0")
    ap.add_argument("--num-envs", type=int, default=4096)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--device", default=None)
    args = ap.parse_args()
    device = wp.get_device(args.device)
    cfg = lookup(args.task).make_cfg({})
    variants = {"full": None, "welded": welded_mjcf(task_posture(cfg, robot_binding(cfg.robot)), MOVING)}
    rows = {}
    for name, mjcf in variants.items():
        model = build(cfg, args.num_envs, device, mjcf)
        rows[name] = {
            "task": args.task,
            "variant": name,
            "device": str(device),
            "num_envs": args.num_envs,
            **measure(cfg, model, args.steps),
        }
        print(json.dumps(rows[name]), flush=True)
    ratio = rows["welded"]["env_steps_per_s"] / rows["full"]["env_steps_per_s"]
    print(json.dumps({"welded_vs_full": round(ratio, 3)}))


if __name__ == "__main__":
    main()
