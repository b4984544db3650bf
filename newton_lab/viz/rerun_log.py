"""Log a batched env to rerun: shapes once (static), body transforms and per-row scalars every step.

Newton's ``ViewerRerun`` always starts a gRPC / web server and only records through it, which does not
fit headless ``.rrd`` recording or tests; this module logs with rerun's own API instead: one entity per
body (``world/<row>/<body>``) carrying its shapes, so a frame costs one ``Transform3D`` per body.
Only the first ``max_worlds`` rows are drawn.
"""

from __future__ import annotations

from pathlib import Path

import newton
import numpy as np
import rerun as rr
import torch
import warp as wp

from ..datasets import read_dataset_info, read_episode
from ..envs import make_env


def _color(rgb) -> list[int]:
    return [int(255 * c) for c in rgb]


class RerunLogger:
    """Streams ``env`` to a rerun sink: ``save`` (a ``.rrd`` file), ``spawn`` (a local viewer) or
    ``connect`` (a viewer's gRPC url). Call ``log_step()`` after each env step."""

    def __init__(self, env, *, save: str | Path | None = None, spawn: bool = False, connect: str | None = None,
                 max_worlds: int = 4, app_id: str = "newton_lab"):
        self.env = env
        self.rows = min(max_worlds, env.num_envs)
        self.rec = rr.RecordingStream(app_id)
        if save is not None:
            self.rec.save(str(save))
        elif connect is not None:
            self.rec.connect_grpc(connect)
        elif spawn:
            self.rec.spawn()
        else:
            raise ValueError("RerunLogger needs a sink: save='file.rrd', spawn=True or connect='rerun+http://...'")
        lay = env.layout
        self._bpw = lay.bodies_per_world
        self._names = [f"b{b:02d}" for b in range(self._bpw)]
        labels = env.model.body_label
        for b in range(self._bpw):
            self._names[b] = labels[b].rsplit("/", 1)[-1] or self._names[b]
        self._step = 0
        self._log_shapes()

    def body_path(self, row: int, body: int) -> str:
        return f"world/{row}/{self._names[body]}"

    def _log_shapes(self) -> None:
        m = self.env.model
        stype = m.shape_type.numpy()
        scale = m.shape_scale.numpy()
        xform = m.shape_transform.numpy()
        sbody = m.shape_body.numpy()
        sworld = m.shape_world.numpy()
        colors = {e.name: _color(c.color) for e, c in zip(self.env.entities.values(), self.env.cfg.entities)}
        flags = m.shape_flags.numpy()
        for s in range(m.shape_count):
            w = int(sworld[s])
            if w >= self.rows or (w < 0 and stype[s] != int(newton.GeoType.PLANE)):
                continue
            label = m.shape_label[s].rsplit("/", 1)[-1]
            color = next((c for name, c in colors.items() if label.startswith(name)), [200, 200, 205])
            b = int(sbody[s])
            if stype[s] == int(newton.GeoType.PLANE):
                self.rec.log("world/ground", rr.Boxes3D(half_sizes=[[3.5, 3.5, 0.005]], centers=[[0, 0, -0.005]],
                                                        colors=[[40, 40, 40]], fill_mode="solid"), static=True)
                continue
            if not flags[s] & int(newton.ShapeFlags.VISIBLE):
                continue
            local = b - w * self._bpw if b >= 0 else -1
            parent = self.body_path(w, local) if local >= 0 else f"world/{w}/static"
            path = f"{parent}/shape_{s}"
            t = xform[s]
            self.rec.log(path, rr.Transform3D(translation=t[:3], quaternion=rr.Quaternion(xyzw=t[3:7])), static=True)
            sx, sy, sz = (float(v) for v in scale[s])
            kind = int(stype[s])
            if kind == int(newton.GeoType.BOX):
                arch = rr.Boxes3D(half_sizes=[[sx, sy, sz]], colors=[color], fill_mode="solid")
            elif kind == int(newton.GeoType.SPHERE):
                arch = rr.Ellipsoids3D(half_sizes=[[sx, sx, sx]], colors=[color], fill_mode="solid")
            elif kind == int(newton.GeoType.CAPSULE):
                arch = rr.Capsules3D(lengths=[2 * sy], radii=[sx], translations=[[0, 0, -sy]], colors=[color])
            elif kind == int(newton.GeoType.CYLINDER):
                arch = rr.Cylinders3D(lengths=[2 * sy], radii=[sx], colors=[color], fill_mode="solid")
            else:
                continue
            self.rec.log(path, arch, static=True)

    def log_step(self, *, reward=None, success=None, body_q: np.ndarray | None = None) -> None:
        """Log the current body poses of the first rows (or ``body_q`` given (rows * bodies, 7)), the TCP
        marker and per-row phase / reward / success scalars at the next ``step`` time."""
        env = self.env
        self.rec.set_time("step", sequence=self._step)
        self.rec.set_time("sim_time", duration=self._step * env.cfg.control_dt)
        q = body_q if body_q is not None else env.state.body_q.numpy()[: self.rows * self._bpw]
        q = np.asarray(q).reshape(self.rows, self._bpw, 7)
        for w in range(self.rows):
            for b in range(self._bpw):
                self.rec.log(self.body_path(w, b),
                             rr.Transform3D(translation=q[w, b, :3], quaternion=rr.Quaternion(xyzw=q[w, b, 3:7])))
            self.rec.log(f"world/{w}/tcp", rr.Points3D([env.tcp_pose[w, :3].cpu().numpy()], radii=[0.01],
                                                       colors=[[255, 200, 0]]))
            self.rec.log(f"metrics/{w}/phase", rr.Scalars(float(env.info["phase"][w])))
            if reward is not None:
                self.rec.log(f"metrics/{w}/reward", rr.Scalars(float(reward[w])))
            if success is not None:
                self.rec.log(f"metrics/{w}/success", rr.Scalars(float(success[w])))
        self._step += 1

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


def replay_episode(path, episode: int = 0, *, save: str | Path | None = None, spawn: bool = False,
                   device: str | None = "cpu") -> np.ndarray:
    """Re-apply a recorded episode's states (robot joints, object poses) frame by frame on a one-row env of
    its task and log them to rerun. Returns the replayed body poses (T, bodies, 7)."""
    info = read_dataset_info(path)
    ids = info["demo_ids"]
    if episode not in ids:
        raise ValueError(f"{path} has no episode {episode}; available: {ids[:5]}{'...' if len(ids) > 5 else ''} "
                         f"({len(ids)} episodes)")
    ep = read_episode(path, episode)
    env = make_env(info["task_id"], num_envs=1, device=device, capture=False)
    logger = RerunLogger(env, save=save, spawn=spawn, max_worlds=1, app_id="newton_lab_replay") \
        if (save is not None or spawn) else None
    robot = ep["states"]["articulation"]["robot"]["joint_position"]
    objects = ep["states"].get("rigid_object", {})
    q = wp.to_torch(env.state.joint_q).view(-1)
    poses = []
    for t in range(len(robot)):
        q[: robot.shape[1]] = torch.as_tensor(robot[t], dtype=torch.float32)
        for name, rec in objects.items():
            c = env.layout.entity_coord[env.entities[name].slot]
            q[c : c + 7] = torch.as_tensor(rec["root_pose"][t], dtype=torch.float32)
        newton.eval_fk(env.model, env.state.joint_q, env.state.joint_qd, env.state)
        body_q = env.state.body_q.numpy().copy()
        poses.append(body_q)
        if logger is not None:
            env._observe()
            logger.log_step(body_q=body_q)
    if logger is not None:
        logger.close()
    return np.stack(poses)

