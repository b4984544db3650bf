"""A control step's physics substeps on MuJoCo-Warp with the state exchanged once, not around every substep.

``SolverMuJoCo.step`` is push (Newton coordinates -> MuJoCo ``qpos`` / ``qvel``), control (drive targets ->
``ctrl``), one MuJoCo-Warp step, pull (``qpos`` / ``qvel`` -> Newton coordinates, then forward kinematics of
every body of the solver's model). Between two substeps of one control step nothing of the env reads the
coordinates or the bodies but the wheel drive, which turns the base twist by the current yaw and reads it from
MuJoCo-Warp's ``qpos`` there (``qpos_source``), so ``ControlStepPhysics`` pushes once, runs each substep's control
and MuJoCo-Warp step, and pulls once. On the GPU that drops ~9 launches a substep of the ~108 (Newton's forward
kinematics among them): PickCube 1.13x at 4096 envs on an H100 (benchmarks history).

Why hand-written: Newton 1.8 has no public call for "several MuJoCo-Warp steps between one push and one pull"
(its ``update_data_interval`` did a part of this and is deprecated). The calls below are ``SolverMuJoCo``'s own
push, control, step and pull methods (private, Newton pinned in ``pyproject.toml``), in the order its ``step``
runs them; ``tests/test_physics_settings.py`` holds this path to ``SolverMuJoCo.step`` substep by substep, so a
Newton upgrade that changes them fails there, not in a task.
"""

from __future__ import annotations

import newton
import numpy as np
import warp as wp

REQUIRED = (
    "_update_mjc_data",
    "_apply_mjc_control",
    "_mujoco_warp_step",
    "_update_newton_state",
    "_update_kinematic_weld_references",
    "mjw_data",
    "mjw_model",
)
"""The ``SolverMuJoCo`` members this path calls."""


def supported(solver) -> bool:
    """Whether ``solver`` is a MuJoCo-Warp ``SolverMuJoCo`` with the members this path calls, running its own
    collision detection, without speculative contacts and with no kinematic body (Newton welds each free root
    to the world by an equality that is active only while the body is kinematic; the env's scenes have none)."""
    if getattr(solver, "use_mujoco_cpu", True) or not all(hasattr(solver, name) for name in REQUIRED):
        return False
    if getattr(solver, "_use_speculative_contacts", False) or not solver.mjw_model.opt.run_collision_detection:
        return False
    welds = getattr(solver, "_kinematic_weld_eq", None)
    return welds is None or not solver.mjw_data.eq_active.numpy()[:, welds.numpy()].any()


class ControlStepPhysics:
    """``begin`` (push), ``substep`` (control + one MuJoCo-Warp step) x decimation, ``end`` (pull) on one solver
    model's ``state`` and ``drive``; every call is launches only, so the sequence records into a graph."""

    def __init__(self, solver, model: newton.Model, sim_dt: float) -> None:
        if not supported(solver):
            raise ValueError(
                "ControlStepPhysics needs Newton's SolverMuJoCo on MuJoCo-Warp (use_mujoco_cpu=False) "
                "with its own collision detection and no kinematic welds"
            )
        self.solver, self.model, self.sim_dt = solver, model, float(sim_dt)

    def begin(self, state: newton.State) -> None:
        """``state``'s coordinates and velocities into MuJoCo-Warp; the step's timestep; the overflow bitmask
        cleared (it then gathers every substep of the control step)."""
        s = self.solver
        s.mjw_model.opt.timestep.fill_(self.sim_dt)
        s.mjw_data.overflow.zero_()
        s._update_mjc_data(s.mjw_data, self.model, state)
        s._update_kinematic_weld_references()  # inactive welds (no kinematic body): keeps Newton's order

    def substep(self, state: newton.State, drive: newton.Control) -> None:
        """``drive``'s targets into MuJoCo's controls, then one MuJoCo-Warp step (``state`` is read for the
        joint-space conversion of the targets only; it is not updated)."""
        s = self.solver
        s._apply_mjc_control(self.model, state, drive, s.mjw_data)
        s._mujoco_warp_step()

    def end(self, state: newton.State) -> None:
        """MuJoCo-Warp's coordinates and velocities back into ``state`` (and its bodies' poses)."""
        s = self.solver
        s._update_newton_state(self.model, state, s.mjw_data, state_prev=state)

    def qpos_source(self, coord: int) -> tuple[wp.array, int, int]:
        """Where coordinate ``coord`` (of one world of the stepped model) lives in MuJoCo-Warp's ``qpos``: (the
        flat ``qpos``, its entries per world, the coordinate's entry in a world), for a kernel reading it between
        substeps. Raises ``ValueError`` where the coordinate has no ``qpos`` entry of its own."""
        s = self.solver
        mj_start = s.mj_q_start.numpy()
        starts = self.model.joint_q_start.numpy()[: len(mj_start) + 1]
        joint = int(np.searchsorted(starts, coord, side="right")) - 1
        if not 0 <= joint < len(mj_start) or mj_start[joint] < 0:
            raise ValueError(f"coordinate {coord} of the stepped model has no MuJoCo qpos entry")
        qpos = s.mjw_data.qpos
        return qpos.flatten(), int(qpos.shape[1]), int(mj_start[joint]) + coord - int(starts[joint])
