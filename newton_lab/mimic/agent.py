"""The generation agent: per row, selects source segments, transforms them into the current object
frames, stitches them with interpolation and tracks the resulting TCP waypoints with batched IK."""

from __future__ import annotations

import numpy as np
import torch
import warp as wp

from ..agents.base import BaseAgent, EpisodeTracker
from ..robots.g1.kinematics import TcpKinematics
from ..task_api.mimic_cfg import MimicCfg
from .poses import closest_symmetric_pose, interpolate_poses, rotation_angle, transform_segment
from .source import SourceDemo


class _RowPlan:
    """One row's generation state for the current attempt."""

    def __init__(self):
        self.subtask = -1
        self.poses = np.zeros((0, 7))
        self.gripper = np.zeros(0)
        self.noisy = np.zeros(0, dtype=bool)
        self.cursor = 0
        self.last_target: np.ndarray | None = None
        self.sources: list[int] = []
        self.settle = 0
        self.done = False


class MimicAgent(BaseAgent):
    """Generates new demonstrations from ``sources`` on any env of the same task.

    IK tracks the waypoints warm-started from the previous step's solution, so a few LM iterations per
    step suffice (consecutive waypoints are millimetres apart)."""

    def __init__(self, sources: list[SourceDemo], cfg: MimicCfg, *, seed: int = 1, ik_iterations: int = 6):
        self.sources = sources
        self.cfg = cfg
        self.rng = np.random.default_rng(seed)
        self.ik_iterations = ik_iterations
        self._env = None

    # ------------------------------------------------------------------ binding
    def _bind(self, env) -> None:
        self._env = env
        n = env.num_envs
        self._kin = TcpKinematics(n, device=env.device, arm=self.cfg.arm)
        names = list(env.action_joint_names)
        self._arm_cols = [names.index(f"{self.cfg.arm}_arm_joint{i}") for i in range(1, 8)]
        grip = f"{self.cfg.arm}_gripper_joint"
        self._grip_col = names.index(grip) if grip in names else None
        self._rows = [_RowPlan() for _ in range(n)]
        self._tracker = EpisodeTracker(n)
        self._q = np.zeros((n, self._kin.robot_coords))
        self._actions = env.current_action().clone()

    def reset(self, env_ids=None) -> None:
        if self._env is not None:
            self._tracker.forget(env_ids)

    # ------------------------------------------------------------------ segments
    def _select(self, sub_idx: int, cur_obj: np.ndarray | None) -> tuple[SourceDemo, int, int] | None:
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
            return cands[int(self.rng.integers(len(cands)))]
        dist = np.array([
            np.linalg.norm(src.objects[sub.object_ref][s, :3] - cur_obj[:3])
            + self.cfg.rot_weight * rotation_angle(src.objects[sub.object_ref][s, 3:7],
                                                   self._frame(sub, cur_obj, src.objects[sub.object_ref][s])[3:7])
            for src, s, _ in cands
        ])
        top = np.argsort(dist)[: max(sub.nn_k, 1)]
        return cands[int(self.rng.choice(top))]

    @staticmethod
    def _frame(sub, cur_obj: np.ndarray, src_obj: np.ndarray) -> np.ndarray:
        """The current object frame to replay in (turned by the object's yaw symmetry toward the source)."""
        if sub.yaw_symmetry is None:
            return cur_obj
        return closest_symmetric_pose(cur_obj, src_obj, sub.yaw_symmetry)

    def _start_subtask(self, r: int, plan: _RowPlan, env_poses: dict[str, np.ndarray], tcp_now: np.ndarray) -> None:
        plan.subtask += 1
        sub = self.cfg.subtasks[plan.subtask]
        cur_obj = env_poses[sub.object_ref][r] if sub.object_ref else None
        pick = self._select(plan.subtask, cur_obj)
        if pick is None:
            plan.subtask = len(self.cfg.subtasks)
            return
        src, start, end = pick
        plan.sources.append(src.demo_id)
        seg = src.target_tcp[start:end]
        if sub.object_ref is not None:
            src_obj = src.objects[sub.object_ref][start]
            seg = transform_segment(seg, src_obj, self._frame(sub, cur_obj, src_obj))
        first = plan.last_target if (self.cfg.interpolate_from_last_target_pose and plan.last_target is not None) else tcp_now
        interp = interpolate_poses(first, seg[0], sub.num_interpolation_steps)
        grip = src.gripper[start:end]
        plan.poses = np.concatenate([interp, seg])
        plan.gripper = np.concatenate([np.full(len(interp), grip[0]), grip])
        plan.noisy = np.concatenate([np.zeros(len(interp), dtype=bool), np.ones(len(seg), dtype=bool)])
        plan.cursor = 0

    # ------------------------------------------------------------------ the agent contract
    def act(self, env, env_ids=None) -> torch.Tensor:
        if self._env is not env:
            self._bind(env)
        n = env.num_envs
        fresh = set(self._tracker.fresh_rows(env).tolist())  # new attempt on these rows
        q_env = wp.to_torch(env.state.joint_q).view(n, -1)[:, : self._kin.robot_coords].cpu().numpy()
        tcp_now = env.tcp_pose.cpu().numpy().astype(np.float64)
        ent = env.entity_poses.cpu().numpy().astype(np.float64)
        env_poses = {name: ent[:, e.slot] for name, e in env.entities.items()}
        targets = tcp_now.copy()
        grip = np.zeros(n)
        noisy = np.zeros(n, dtype=bool)
        for r in range(n):
            plan = self._rows[r]
            if r in fresh:
                plan = self._rows[r] = _RowPlan()
                self._q[r] = q_env[r]
            while not plan.done and plan.cursor >= len(plan.poses):
                if plan.subtask + 1 >= len(self.cfg.subtasks):
                    plan.done = True
                    break
                self._start_subtask(r, plan, env_poses, tcp_now[r])
            if plan.done:
                plan.settle += 1
                targets[r] = plan.last_target if plan.last_target is not None else tcp_now[r]
                grip[r] = plan.gripper[-1] if len(plan.gripper) else 0.0
                continue
            targets[r] = plan.poses[plan.cursor]
            grip[r] = plan.gripper[plan.cursor]
            noisy[r] = plan.noisy[plan.cursor]
            plan.last_target = targets[r]
            plan.cursor += 1
        seed = q_env.copy()
        seed[:, self._kin.arm_coords] = self._q[:, self._kin.arm_coords]
        q = self._kin.solve(seed, targets[:, :3], targets[:, 3:7], iterations=self.ik_iterations)
        self._q = q.astype(np.float64)
        arm = q[:, self._kin.arm_coords]
        noise = np.array([self.cfg.subtasks[min(max(p.subtask, 0), len(self.cfg.subtasks) - 1)].action_noise
                          for p in self._rows])
        arm = arm + noisy[:, None] * noise[:, None] * self.rng.standard_normal(arm.shape)
        out = self._actions
        out[:, self._arm_cols] = torch.as_tensor(arm, dtype=torch.float32, device=out.device)
        if self._grip_col is not None:
            out[:, self._grip_col] = torch.as_tensor(grip, dtype=torch.float32, device=out.device)
        return out

    def done(self, env) -> torch.Tensor:
        """Rows whose attempt played every segment and held the last target for ``settle_steps``."""
        flags = [p.done and p.settle >= self.cfg.settle_steps for p in self._rows] if self._env is env else []
        return torch.as_tensor(flags or [False] * env.num_envs, device=env.torch_device)
