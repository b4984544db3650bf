"""The generation agent: per row, selects source segments, transforms them into the current object
frames, stitches them with interpolation and tracks the resulting TCP waypoints with batched IK."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch
import warp as wp

from ..agents.base import BaseAgent
from ..task_api.mimic_cfg import MimicCfg
from .poses import closest_symmetric_pose, interpolate_poses, rotation_angle, transform_segments
from .source import SourceDemo


class _Pick(NamedTuple):
    """A row's source segment for its next subtask: steps ``[start, end)`` of ``src``; for a subtask tied to an
    object, the object's pose in the source at ``start`` and the current object frame to replay in."""

    sub: Any
    src: SourceDemo
    start: int
    end: int
    src_obj: np.ndarray | None
    frame: np.ndarray | None


class _RowPlan:
    """One row's plan for the current attempt: its subtask, the segment planned last, the sources used (the
    step state, cursor, done flag and last target, is in the agent's per-row arrays)."""

    def __init__(self):
        self.subtask = -1
        self.poses = np.zeros((0, 7))
        self.gripper = np.zeros(0)
        self.noisy = np.zeros(0, dtype=bool)
        self.sources: list[int] = []


class MimicAgent(BaseAgent):
    """Generates new demonstrations from ``sources`` on any env of the same task.

    IK tracks the waypoints warm-started from the previous step's solution, so a few LM iterations per
    step suffice (consecutive waypoints are millimetres apart)."""

    def __init__(self, sources: list[SourceDemo], cfg: MimicCfg, *, seed: int = 1, ik_iterations: int = 6):
        self.sources = sources
        self.cfg = cfg
        self.rng = np.random.default_rng(seed)
        self.ik_iterations = ik_iterations

    # ------------------------------------------------------------------ binding
    def setup(self, env) -> None:
        n = env.num_envs
        self._kin = env.robot.kinematics(n, device=env.device, arm=self.cfg.arm)
        names, arm = list(env.action_joint_names), env.robot.arm(self.cfg.arm)
        self._arm_cols = [names.index(j) for j in arm.joints]
        grip = arm.gripper
        self._grip_col = names.index(grip) if grip in names else None
        self._rows = [_RowPlan() for _ in range(n)]
        self._q = np.zeros((n, self._kin.robot_coords))
        self._actions = env.current_action().clone()
        # per-row step state, indexed for every row at once (planned per row only at subtask starts)
        self._poses = np.zeros((n, 0, 7))
        """(N, L, 7) TCP waypoints of each row's current segment (interpolation + transformed source)."""
        self._gripper, self._noisy = np.zeros((n, 0)), np.zeros((n, 0), dtype=bool)
        self._cursor, self._length = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        self._done, self._settle = np.zeros(n, dtype=bool), np.zeros(n, dtype=np.int64)
        self._subtask = np.zeros(n, dtype=np.int64)
        self._last_target, self._has_last = np.zeros((n, 7)), np.zeros(n, dtype=bool)
        self._last_grip = np.zeros(n)
        self._noise_of = np.array([sub.action_noise for sub in self.cfg.subtasks], dtype=np.float64)

    # ------------------------------------------------------------------ segments
    def _select(self, sub_idx: int, cur_obj: np.ndarray | None) -> _Pick | None:
        sub = self.cfg.subtasks[sub_idx]
        cands = []
        for src in self.sources:
            ends = src.boundaries(self.cfg, self.rng)
            if ends is None:
                continue
            start = 0 if sub_idx == 0 else ends[sub_idx - 1]
            cands.append((src, start, ends[sub_idx]))
        if not cands:
            return None
        if sub.object_ref is None or cur_obj is None:
            return _Pick(sub, *cands[int(self.rng.integers(len(cands)))], None, None)
        src_obj = np.stack([src.objects[sub.object_ref][s] for src, s, _ in cands])  # (K, 7) at each segment start
        frames = self._frame(sub, cur_obj, src_obj)
        dist = np.linalg.norm(src_obj[:, :3] - cur_obj[:3], axis=1) + self.cfg.rot_weight * rotation_angle(
            src_obj[:, 3:7], frames[:, 3:7]
        )
        top = np.argsort(dist)[: max(sub.nn_k, 1)]
        k = int(self.rng.choice(top))
        return _Pick(sub, *cands[k], src_obj[k], frames[k])

    @staticmethod
    def _frame(sub, cur_obj: np.ndarray, src_obj: np.ndarray) -> np.ndarray:
        """The current object frame to replay in (turned by the object's yaw symmetry toward the source pose
        ``src_obj`` (7,) or each of (K, 7))."""
        if sub.yaw_symmetry is None:
            return np.broadcast_to(cur_obj, np.shape(src_obj))
        return closest_symmetric_pose(cur_obj, src_obj, sub.yaw_symmetry)

    def _pick(self, r: int, plan: _RowPlan, env_poses: dict[str, np.ndarray]) -> _Pick | None:
        """Row ``r``'s next subtask and its source segment (``_select``: the row's random draws); None when no
        source fits (the attempt ends with an empty plan)."""
        plan.subtask += 1
        sub = self.cfg.subtasks[plan.subtask]
        pick = self._select(plan.subtask, env_poses[sub.object_ref][r] if sub.object_ref else None)
        if pick is None:
            plan.subtask = len(self.cfg.subtasks)
            plan.poses, plan.gripper, plan.noisy = np.zeros((0, 7)), np.zeros(0), np.zeros(0, dtype=bool)
            return None
        plan.sources.append(pick.src.demo_id)
        return pick

    def _start_subtasks(self, rows: list[int], env_poses: dict[str, np.ndarray], tcp_now: np.ndarray) -> None:
        """Rows ``rows`` start their next subtask: per row the source pick (in row order, so the random draws
        do not depend on batching), then every picked segment moved into its object frame at once."""
        picks = [(r, self._pick(r, self._rows[r], env_poses)) for r in rows]
        picked = [(r, p) for r, p in picks if p is not None]
        segs = [p.src.target_tcp[p.start : p.end] for _, p in picked]
        moved = [i for i, (_, p) in enumerate(picked) if p.frame is not None]
        if moved:
            out = transform_segments(
                [segs[i] for i in moved],
                np.stack([picked[i][1].src_obj for i in moved]),
                np.stack([picked[i][1].frame for i in moved]),
            )
            for i, seg in zip(moved, out):
                segs[i] = seg
        for (r, p), seg in zip(picked, segs):
            plan = self._rows[r]
            use_last = self.cfg.interpolate_from_last_target_pose and self._has_last[r]
            interp = interpolate_poses(
                self._last_target[r] if use_last else tcp_now[r], seg[0], p.sub.num_interpolation_steps
            )
            grip = p.src.gripper[p.start : p.end]
            plan.poses = np.concatenate([interp, seg])
            plan.gripper = np.concatenate([np.full(len(interp), grip[0]), grip])
            plan.noisy = np.concatenate([np.zeros(len(interp), dtype=bool), np.ones(len(seg), dtype=bool)])
        for r, _ in picks:
            self._load(r, self._rows[r])
            if not self._length[r]:  # no source fitted: the attempt is over
                self._done[r] = True

    # ------------------------------------------------------------------ the agent contract
    def _plan_rows(
        self, rows, fresh: set[int], q_env: np.ndarray, env_poses: dict[str, np.ndarray], tcp_now: np.ndarray
    ) -> None:
        """Per-row Python only where a row starts an attempt or a subtask (bookkeeping and the source pick); the
        segments are moved for all those rows at once and copied into the padded step buffers that :meth:`act`
        indexes for every row at once."""
        starting = []
        for r in rows:
            plan = self._rows[r]
            if r in fresh:
                plan = self._rows[r] = _RowPlan()
                self._q[r] = q_env[r]
                self._cursor[r], self._length[r], self._done[r], self._settle[r] = 0, 0, False, 0
                self._has_last[r], self._last_grip[r] = False, 0.0
            if self._done[r] or self._cursor[r] < self._length[r]:
                continue
            if plan.subtask + 1 >= len(self.cfg.subtasks):
                self._done[r] = True
            else:
                starting.append(r)
        if starting:
            self._start_subtasks(starting, env_poses, tcp_now)

    def _load(self, r: int, plan: _RowPlan) -> None:
        """Row ``r``'s new segment into the step buffers (grown to the longest segment so far)."""
        length = len(plan.poses)
        if length > self._poses.shape[1]:
            grow = length - self._poses.shape[1]
            self._poses = np.pad(self._poses, ((0, 0), (0, grow), (0, 0)))
            self._gripper = np.pad(self._gripper, ((0, 0), (0, grow)))
            self._noisy = np.pad(self._noisy, ((0, 0), (0, grow)))
        self._poses[r, :length], self._gripper[r, :length] = plan.poses, plan.gripper
        self._noisy[r, :length] = plan.noisy
        self._cursor[r], self._length[r] = 0, length
        self._subtask[r] = min(max(plan.subtask, 0), len(self.cfg.subtasks) - 1)
        if length:
            self._last_grip[r] = plan.gripper[-1]

    def act(self, env, env_ids=None) -> torch.Tensor:
        n = env.num_envs
        fresh = set(self.fresh_rows(env).tolist())  # new attempt on these rows
        q_env = wp.to_torch(env.state.joint_q).view(n, -1)[:, : self._kin.robot_coords].cpu().numpy()
        tcp_now = env.buffers.tcp_pose.cpu().numpy().astype(np.float64)
        due = sorted(fresh | set(np.nonzero(~self._done & (self._cursor >= self._length))[0].tolist()))
        if due:
            ent = env.buffers.entity_poses.cpu().numpy().astype(np.float64)
            self._plan_rows(due, fresh, q_env, {name: ent[:, e.slot] for name, e in env.task.entities.items()}, tcp_now)
        # every row at once: the next waypoint of a playing row; a finished row holds its last target
        playing = ~self._done
        targets = tcp_now.copy()
        grip = np.zeros(n)
        noisy = np.zeros(n, dtype=bool)
        if playing.any():  # a playing row's cursor is inside its segment (planned just above)
            rows, cursor = np.nonzero(playing)[0], self._cursor[playing]
            targets[rows], grip[rows], noisy[rows] = (
                self._poses[rows, cursor],
                self._gripper[rows, cursor],
                self._noisy[rows, cursor],
            )
        held = ~playing & self._has_last
        targets[held] = self._last_target[held]
        grip[~playing] = self._last_grip[~playing]
        self._settle[~playing] += 1
        self._last_target[playing], self._has_last[playing] = targets[playing], True
        self._cursor[playing] += 1
        seed = q_env.copy()
        seed[:, self._kin.arm_coords] = self._q[:, self._kin.arm_coords]
        q = self._kin.solve(seed, targets[:, :3], targets[:, 3:7], iterations=self.ik_iterations)
        self._q = q.astype(np.float64)
        arm = q[:, self._kin.arm_coords]
        arm = arm + noisy[:, None] * self._noise_of[self._subtask][:, None] * self.rng.standard_normal(arm.shape)
        out = self._actions
        out[:, self._arm_cols] = torch.as_tensor(arm, dtype=torch.float32, device=out.device)
        if self._grip_col is not None:
            out[:, self._grip_col] = torch.as_tensor(grip, dtype=torch.float32, device=out.device)
        return out

    def done(self, env) -> torch.Tensor:
        """Rows whose attempt played every segment and held the last target for ``settle_steps``."""
        if self.bound_env is not env:
            return torch.zeros(env.num_envs, dtype=torch.bool, device=env.torch_device)
        return torch.as_tensor(self._done & (self._settle >= self.cfg.settle_steps), device=env.torch_device)
