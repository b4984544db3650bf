"""PlannerAgent: resolves a motion plan per row from live poses, solves every TCP target with batched
``newton.ik`` for all rows at once, and stores the joint-space trajectory in device buffers; ``act`` is a
single gather kernel. Rows whose episode restarted are re-planned alone."""

from __future__ import annotations

import math

import numpy as np
import torch
import warp as wp

from ...kernels.planner import gather_plan_actions
from ...robots.quaternions import quat_mul
from ...task_api.motion_plan import MotionPlan, yaw_of
from ...task_api.registry import lookup
from ..base import BaseAgent

REPLAN_ROWS = 16
"""Env rows per restarted row of a default re-plan batch (``PlannerAgent.replan_batch``)."""
REPLAN_MIN_ROWS = 128
"""Below this many rows every restarted row is planned at once (on a CPU a solve's cost follows its rows)."""
REPLAN_WAIT = 12
"""Default most ``act`` calls a restarted row waits for its batch (``PlannerAgent.replan_wait``)."""
REFINE_POSITION_M = 1e-3
"""A solve whose TCP misses its target by more than this [m] gets ``refine_iterations`` more LM steps."""
REFINE_ROTATION_RAD = math.radians(0.5)
"""Same for the TCP orientation [rad] (converged solves sit at 0.06-0.08 deg, the float32 floor)."""


class PlannerAgent(BaseAgent):
    """Executes ``plan`` for every row; see ``newton_lab.task_api.motion_plan`` for the step format."""

    def __init__(
        self,
        plan: MotionPlan,
        *,
        ik_iterations: int = 16,
        refine_iterations: int = 32,
        replan_batch: int | None = None,
        replan_wait: int | None = None,
    ):
        self.plan = plan
        self.ik_iterations = ik_iterations
        """LM steps of every IK solve (the targets of PickCube, StackCube, LiftCube, Reach and SortToShelf converge
        within 12: joints equal to 48 steps' to 5e-6 rad)."""
        self.refine_iterations = refine_iterations
        """Further LM steps, from the first solve's result, for the rows still off by more than
        ``REFINE_POSITION_M`` or ``REFINE_ROTATION_RAD`` (far or unreachable targets, e.g. PickToShelf's)."""
        self.replan_batch = replan_batch
        """Restarted rows gathered before they are planned together; ``None``: one per ``REPLAN_ROWS`` env rows
        from ``REPLAN_MIN_ROWS`` rows on (256 at 4096), else 1 (every restarted row planned at once). A plan's IK
        solves cost the same for 1 row or 500 on a GPU (chains of small kernels), so at 4096 rows, where ~28 episodes
        restart every step, planning them every several steps instead of every step cuts the agent's time by that
        factor (benchmarks history: 4.1-5.3 -> 2.6-2.9 ms a step on an H100, batches of 64 -> 256)."""
        self.replan_wait = replan_wait
        """Most ``act`` calls a restarted row holds its reset targets before it is planned (``None``:
        ``REPLAN_WAIT``). ``collect`` and ``evaluate`` start its episode when its plan comes (``holding``), so the
        wait adds no still frames to a demo; it only leaves the row idle meanwhile."""
        self._held: np.ndarray | None = None  # rows whose last action held while they waited (``holding``)
        self.plan_failures = 0
        """Rows whose IK missed a target by more than the plan's tolerances (cumulative)."""

    @classmethod
    def from_task(cls, task_id: str, task_options: dict | None = None, **kwargs) -> PlannerAgent:
        """The expert for ``task_id`` (its registered motion plan, built for ``task_options`` when the plan
        is a Python factory taking them, e.g. ``sorting_object``)."""
        task = lookup(task_id)
        plan = task.make_expert(task.accepted(task_options)) if task.expert is not None else None
        if not isinstance(plan, MotionPlan):
            raise ValueError(f"task {task_id!r} has no motion plan; use another agent (e.g. a policy or nav agent)")
        return cls(plan, **kwargs)

    # ------------------------------------------------------------------ binding to an env
    def setup(self, env) -> None:
        self._robot = env.robot
        n, dev = env.num_envs, env.device
        arm = self.plan.arm
        arm_joints = env.robot.arm(arm).joints
        names = list(env.action_joint_names)
        missing = [j for j in arm_joints if j not in names]
        if missing:
            raise ValueError(f"env {env.task_id} has no action columns for {missing}; the plan drives the {arm} arm")
        self._arm_cols = wp.array([names.index(j) for j in arm_joints], dtype=int, device=dev)
        gripper = env.robot.arm(arm).gripper
        self._gripper_col = names.index(gripper) if gripper in names else -1
        self._arm_coords = env.joints.coords(arm_joints)
        self._arm_q = wp.array(self._arm_coords, dtype=int, device=dev)
        self._joint_q = env.state.joint_q.reshape((n, -1))  # a view of the live state (fixed: the step is captured)
        self._robot_coords = env.joints.robot_coords
        self._kin = env.robot.kinematics(n, device=dev, arm=arm)
        with wp.ScopedDevice(dev):
            k = max(self._num_waypoints(), 1)
            self._waypoints = wp.zeros((n, k, len(arm_joints) + 1), dtype=float)  # the arm's joints, the gripper
            self._start_q = wp.zeros((n, len(arm_joints)), dtype=float)
            self._seg_start = wp.zeros((n, k), dtype=int)
            self._seg_interp = wp.zeros((n, k), dtype=int)
            self._seg_settle_at = wp.full((n, k), -1, dtype=int)
            self._num_segments = wp.zeros(n, dtype=int)
            self._plan_end = wp.zeros(n, dtype=int)
            self._cursor = wp.zeros(n, dtype=int)
            self._plan_length = np.zeros(n, dtype=np.int64)
            self._actions = wp.from_torch(env.current_action().contiguous())
        self._waiting_since = np.full(n, -1, dtype=np.int64)  # act count at which a row began waiting; -1: none
        self._acts = 0
        self._batch = (
            self.replan_batch
            if self.replan_batch is not None
            else max(1, n // REPLAN_ROWS)
            if n >= REPLAN_MIN_ROWS
            else 1
        )
        self._wait = self.replan_wait if self.replan_wait is not None else REPLAN_WAIT

    # ------------------------------------------------------------------ planning
    def _num_waypoints(self) -> int:
        """Joint-space waypoints of the plan: one per step, ``linear`` for straight-line TCP steps."""
        return sum(s.linear if s.target is not None else 1 for s in self.plan.steps)

    def _poses(self, env, rows: np.ndarray) -> dict[str, np.ndarray]:
        ent = env.buffers.entity_poses.detach().cpu().numpy()[rows].astype(np.float64)
        poses = {name: ent[:, e.slot] for name, e in env.task.entities.items()}
        poses["tcp"] = env.buffers.tcp_pose.detach().cpu().numpy()[rows].astype(np.float64)
        poses["command"] = env.info["command"].detach().cpu().numpy()[rows].astype(np.float64)
        q = wp.to_torch(env.state.joint_q).view(env.num_envs, -1).cpu().numpy()[rows]
        bx, by, byaw = env.joints.coords(env.robot.base_planar_joints)
        yaw = q[:, byaw]
        poses["base"] = np.stack(
            [
                q[:, bx],
                q[:, by],
                np.zeros_like(yaw),
                np.zeros_like(yaw),
                np.zeros_like(yaw),
                np.sin(yaw / 2),
                np.cos(yaw / 2),
            ],
            axis=1,
        )
        return poses

    def _target_quat(self, step, poses: dict[str, np.ndarray], r: int) -> np.ndarray:
        if callable(step.quat):
            return np.asarray(step.quat(poses), dtype=np.float64)
        if step.quat is not None:
            return np.tile(np.asarray(step.quat, dtype=np.float64), (r, 1))
        top = np.tile(np.asarray(self._robot.top_down_tcp_quat, dtype=np.float64), (r, 1))
        if step.align_yaw is None:
            return top
        yaw = yaw_of(poses[step.align_yaw][:, 3:7])
        yaw = (yaw + math.pi / 4) % (math.pi / 2) - math.pi / 4  # a cube looks the same every 90 deg
        turn = np.stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)
        return quat_mul(turn, top)

    def _solve(
        self, q_seed: np.ndarray, rows: np.ndarray, pos: np.ndarray, quat: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """IK for the given rows only (the other rows of ``q_seed`` are returned unchanged): ``ik_iterations`` LM
        steps for all, ``refine_iterations`` more for those still off. Returns all (N, 34) coordinates and the
        rows' TCP position error [m] from forward kinematics of the solutions. On a GPU a solve is a chain of
        ~16 small kernels per step, so its time follows the step count, not the rows."""
        q = q_seed.copy()
        q_rows = self._kin.solve(q_seed[rows], pos, quat, iterations=self.ik_iterations)
        err, turn = self._errors(q_rows, pos, quat)
        off = np.flatnonzero((err > REFINE_POSITION_M) | (turn > REFINE_ROTATION_RAD))
        if len(off) and self.refine_iterations > 0:
            q_rows[off] = self._kin.solve(q_rows[off], pos[off], quat[off], iterations=self.refine_iterations)
            err[off] = self._errors(q_rows[off], pos[off], quat[off])[0]
        q[rows] = q_rows
        return q, err

    def _errors(self, q: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP position error [m] and rotation error [rad] of coordinate rows ``q`` against the targets."""
        tcp = self._kin.tcp_poses(q)
        dot = np.abs(np.sum(tcp[:, 3:7] * np.asarray(quat, dtype=np.float64), axis=1)).clip(0.0, 1.0)
        return np.linalg.norm(tcp[:, :3] - pos, axis=1), 2.0 * np.arccos(dot)

    def _plan_rows(self, env, rows: np.ndarray) -> None:
        plan, r = self.plan, len(rows)
        poses = self._poses(env, rows)
        q_env = wp.to_torch(env.state.joint_q).view(env.num_envs, -1)[:, : self._robot_coords].cpu().numpy()
        q_seed = q_env.copy()
        prev = q_env[rows][:, self._arm_coords].astype(np.float64)
        start = prev.copy()
        k = self._num_waypoints()
        arm = len(self._arm_coords)
        way = np.zeros((r, k, arm + 1))
        seg_start = np.zeros((r, k), dtype=np.int64)
        seg_interp = np.zeros((r, k), dtype=np.int64)
        settle_at = np.full((r, k), -1, dtype=np.int64)
        frame = np.zeros(r, dtype=np.int64)
        failed = np.zeros(r, dtype=bool)
        tcp_prev = poses["tcp"][:, :3].copy()  # start of the next straight-line TCP move
        solved = None  # (point, quat, error) of the last IK solve, whose solution q_seed holds
        i = 0
        early = _early_settles(plan)
        for n_step, step in enumerate(plan.steps):
            gripper = self._robot.gripper_open if step.gripper_open else self._robot.gripper_closed
            moves = step.target is not None or step.joints is not None
            if step.joints is not None:
                targets = [np.tile(np.asarray(step.joints, dtype=np.float64), (r, 1))]
            elif step.target is not None:
                goal = step.target.resolve(poses) if hasattr(step.target, "resolve") else step.target(poses)
                quat = self._target_quat(step, poses, r)
                targets = []
                for j in range(1, step.linear + 1):
                    point = tcp_prev + (goal - tcp_prev) * (j / step.linear)
                    if solved is not None and np.array_equal(point, solved[0]) and np.array_equal(quat, solved[1]):
                        q_all, err = q_seed, solved[2]  # the pose just solved (e.g. the gripper opens where it is)
                    else:
                        q_all, err = self._solve(q_seed, rows, point, quat)
                        solved = (point, quat, err)
                    targets.append(q_all[rows][:, self._arm_coords].astype(np.float64))
                    q_seed = q_all
                    failed |= err > plan.position_tolerance
            else:
                targets = [prev]
            speed = step.max_joint_step or plan.max_joint_step
            settle = plan.settle_steps if moves and step.settle else 0
            for j, q_k in enumerate(targets):
                last = j == len(targets) - 1
                n_interp = np.ceil(np.abs(q_k - prev).max(axis=1) / speed).astype(np.int64)
                n_interp = np.maximum(n_interp, 1 if moves else 0)
                way[:, i, :arm] = q_k
                way[:, i, arm] = gripper
                seg_start[:, i] = frame
                seg_interp[:, i] = n_interp
                if last and settle and early[n_step]:
                    settle_at[:, i] = frame + n_interp + max(step.hold - 1, 0)
                frame = frame + n_interp + (max(step.hold - 1, 0) + settle if last else 0)
                frame = np.maximum(frame, seg_start[:, i] + 1)
                prev = q_k
                i += 1
            if step.target is not None:
                tcp_prev = goal
            elif step.joints is not None:
                q_fk = q_env[rows].astype(np.float64).copy()
                q_fk[:, self._arm_coords] = prev
                tcp_prev = self._kin.tcp_poses(q_fk)[:, :3]
        self.plan_failures += int(failed.sum())
        self._plan_length[rows] = frame
        self._upload(env, rows, k, way, start, seg_start, seg_interp, settle_at, frame)

    def _upload(self, env, rows, k: int, way, start, seg_start, seg_interp, settle_at, frame) -> None:
        """The planned rows' waypoints, segments and settles into the device arrays the action kernel reads, each
        row's cursor at its first segment."""
        idx = torch.as_tensor(rows, device=env.torch_device)
        t = wp.to_torch
        t(self._waypoints)[idx] = torch.as_tensor(way, dtype=torch.float32, device=env.torch_device)
        t(self._start_q)[idx] = torch.as_tensor(start, dtype=torch.float32, device=env.torch_device)
        t(self._seg_start)[idx] = torch.as_tensor(seg_start, dtype=torch.int32, device=env.torch_device)
        t(self._seg_interp)[idx] = torch.as_tensor(seg_interp, dtype=torch.int32, device=env.torch_device)
        t(self._seg_settle_at)[idx] = torch.as_tensor(settle_at, dtype=torch.int32, device=env.torch_device)
        t(self._plan_end)[idx] = torch.as_tensor(frame, dtype=torch.int32, device=env.torch_device)
        t(self._num_segments)[idx] = k
        t(self._cursor)[idx] = 0

    # ------------------------------------------------------------------ the agent contract
    def reset(self, env_ids=None) -> None:
        """Forces a re-plan of ``env_ids`` (all rows when ``None``) at the next ``act``."""
        super().reset(env_ids)

    def act(self, env, env_ids=None) -> torch.Tensor:
        rows = self.fresh_rows(env, env_ids)
        if env_ids is not None or self._batch <= 1:
            rows = np.union1d(rows, np.flatnonzero(self._waiting_since >= 0))
        elif rows.size or (self._waiting_since >= 0).any():
            rows = self._rows_due(env, rows)
        if rows.size:
            self._plan_rows(env, rows)
            self._waiting_since[rows] = -1
        self._acts += 1
        self._held = self._waiting_since >= 0
        wp.launch(
            gather_plan_actions,
            dim=env.num_envs,
            inputs=[
                self._waypoints,
                self._start_q,
                self._seg_start,
                self._seg_interp,
                self._seg_settle_at,
                self._num_segments,
                self._plan_end,
                self._cursor,
                self._joint_q,  # the settle test reads the arm's joints
                self._arm_q,
                float(self.plan.settle_tolerance),
                self._arm_cols,
                self._gripper_col,
                self._actions,
            ],
            device=env.device,
        )
        return wp.to_torch(self._actions)

    def holding(self) -> np.ndarray | None:
        """Rows whose last action was a hold while they waited for their plan (numpy bool), or None before the
        first ``act``. ``collect`` and ``evaluate`` start such a row's episode over from the step its plan
        begins: a recorded demo has no still frames ahead of its motion, and episode lengths do not count the
        wait."""
        return self._held

    def _rows_due(self, env, fresh: np.ndarray) -> np.ndarray:
        """Restarted rows join the waiting ones (holding their reset targets); all of them are due once there
        are ``replan_batch`` or the oldest has waited ``replan_wait`` calls (the defaults: ``setup``)."""
        if fresh.size:
            self._waiting_since[fresh] = self._acts
            idx = torch.as_tensor(fresh, device=env.torch_device)
            wp.to_torch(self._num_segments)[idx] = 0  # the gather leaves their action rows alone
            wp.to_torch(self._actions)[idx] = env.current_action()[idx]
            self._plan_length[fresh] = np.iinfo(np.int64).max  # not done while waiting
        waiting = np.flatnonzero(self._waiting_since >= 0)
        oldest = self._acts - int(self._waiting_since[waiting].min())
        due = waiting.size >= self._batch or oldest >= self._wait
        return waiting if due else np.zeros(0, dtype=np.int64)

    def done(self, env) -> torch.Tensor:
        """Rows whose plan has played to its last frame."""
        cursor = wp.to_torch(self._cursor).cpu().numpy()
        return torch.as_tensor(cursor >= self._plan_length, device=env.torch_device)


def _early_settles(plan) -> list[bool]:
    """Per step of ``plan``: whether its settle may end early, once the arm is there (``MotionPlan.settle_tolerance``);
    never around the gripper opening: before it (the carried cube still swings) nor in the step that opens it (the
    fingers are still opening)."""
    steps = plan.steps
    opening = [j > 0 and s.gripper_open and not steps[j - 1].gripper_open for j, s in enumerate(steps)]
    early = [
        plan.settle_steps > 0 and plan.settle_tolerance > 0 and not o and not (j + 1 < len(steps) and opening[j + 1])
        for j, o in enumerate(opening)
    ]
    return early
