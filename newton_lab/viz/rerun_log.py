"""Log a batched env to rerun: every model shape once (static), body transforms and per-row scalars every
step, episode starts / ends as events, with a default blueprint (``newton_lab.viz.blueprint``).

Newton's ``ViewerRerun`` always starts a gRPC / web server and only records through it, which does not
fit headless ``.rrd`` recording or tests; this module logs with rerun's own API instead: one entity per
body (``world/<row>/<body>``) carrying its shapes (``newton_lab.viz.shapes``), so a frame costs one
``Transform3D`` per body. Only the first ``max_worlds`` rows are drawn, side by side on a grid
``row_spacing`` [m] apart (Newton's worlds all sit at the origin). An env with cameras also shows each camera as
a pinhole with its image streams (``newton_lab.viz.camera_log``), and the blueprint a 2D panel per camera.
"""

from __future__ import annotations

from pathlib import Path

import newton
import numpy as np
import rerun as rr
import torch
import warp as wp

from ..datasets import read_dataset_info, read_episode, state_tree
from ..datasets.files.output_paths import output_path
from ..envs import make_env
from ..envs.recorder import recorded_scene
from .blueprint import default_blueprint, eye_for
from .camera_log import CameraStream, dataset_streams, env_streams, log_camera_frame, log_camera_statics, mount_poses
from .shapes import entity_name, log_model_shapes, row_offsets


class RerunLogger:
    """Streams ``env`` to a rerun sink: ``save`` (a ``.rrd`` file; its folder is created), ``spawn`` (a
    local viewer) or ``connect`` (a viewer's gRPC url), with the default blueprint. Call ``on_step(reward,
    info)`` (or ``log_step``) after each env step; ``close()`` at the end. ``path`` is the ``.rrd`` written
    (absolute) or None; ``shape_paths`` maps each logged model shape index to its entity path.
    ``episodes_per_row``: a row is no longer drawn once that many of its episodes have ended (None: all).
    ``images``: log the env's cameras (pinhole + images of the drawn rows) every ``image_every``-th logged step
    (a step whose images nobody read yet renders them: CPU time); ``jpeg_quality`` (1-100) stores RGB as JPEG instead of
    raw pixels; ``cameras`` replaces the env's cameras (a replay passes the recorded ones and the frames to
    ``log_step``)."""

    def __init__(
        self,
        env,
        *,
        save: str | Path | None = None,
        spawn: bool = False,
        connect: str | None = None,
        max_worlds: int = 4,
        app_id: str = "newton_lab",
        row_spacing: float = 2.5,
        episodes_per_row: int | None = None,
        images: bool = True,
        image_every: int = 1,
        jpeg_quality: int | None = None,
        cameras: list[CameraStream] | None = None,
    ):
        if save is None and connect is None and not spawn:
            raise ValueError("RerunLogger needs a sink: save='file.rrd', spawn=True or connect='rerun+http://...'")
        if not isinstance(max_worlds, int) or max_worlds < 1:
            raise ValueError(f"max_worlds must be an integer >= 1, got {max_worlds!r}")
        if episodes_per_row is not None and (not isinstance(episodes_per_row, int) or episodes_per_row < 1):
            raise ValueError(f"episodes_per_row must be None or an integer >= 1, got {episodes_per_row!r}")
        if not isinstance(image_every, int) or image_every < 1:
            raise ValueError(f"image_every must be an integer >= 1 (log images every n-th step), got {image_every!r}")
        if jpeg_quality is not None and (not isinstance(jpeg_quality, int) or not 1 <= jpeg_quality <= 100):
            raise ValueError(f"jpeg_quality must be None (raw RGB) or an integer in [1, 100], got {jpeg_quality!r}")
        self.episodes_per_row = episodes_per_row
        self.image_every, self.jpeg_quality = image_every, jpeg_quality
        self.cameras = (list(cameras) if cameras is not None else env_streams(env)) if images else []
        """The cameras logged (``camera_log.CameraStream``); empty without images or cameras."""
        self.env = env
        self.rows = min(max_worlds, env.num_envs)
        self._bpw = env.sim.bodies_per_world
        taken = {"static", "tcp"}  # reserved names under world/<row>
        self._names = [entity_name(env.model.body_label[b] or f"b{b:02d}", taken) for b in range(self._bpw)]
        self.rec = rr.RecordingStream(app_id)
        self.path = None if save is None else Path(save).resolve()
        offsets = row_offsets(self.rows, row_spacing)
        body_paths = {w * self._bpw + b: self.body_path(w, b) for w in range(self.rows) for b in range(self._bpw)}
        logged = log_model_shapes(self.rec, env.model, body_paths, self.rows, offsets)
        self.shape_paths = logged.paths
        for w in range(self.rows):
            for cam in self.cameras:
                log_camera_statics(self.rec, w, cam)
        self.blueprint = default_blueprint(
            self.rows, eye=self._eye(), hidden=logged.hidden, cameras={c.name: c.data for c in self.cameras}
        )
        if self.path is not None:
            output_path(self.path)
            self.rec.save(str(self.path), default_blueprint=self.blueprint)
        elif connect is not None:
            self.rec.connect_grpc(connect, default_blueprint=self.blueprint)
        else:
            self.rec.spawn(default_blueprint=self.blueprint)
        self._step = 0
        self._episodes = self._episode_count()
        self._ended = [0] * self.rows  # episodes ended per row, in this recording
        self._open = [True] * self.rows  # the row's episode has not been logged as ended
        self._frames = [0] * self.rows  # frames logged of the row's episode

    def body_path(self, row: int, body: int) -> str:
        """Entity path of ``body`` (index within a world) of ``row``."""
        return f"world/{row}/{self._names[body]}"

    def _eye(self):
        q = self.env.state.body_q.numpy()[: self._bpw]
        poses = self.env.buffers.entity_poses[0, :, :3].cpu().numpy()
        robot = q[0, :3]
        return eye_for(robot, poses.mean(axis=0) if len(poses) else robot + np.array([1.0, 0.0, 0.0]))

    def _episode_count(self) -> np.ndarray:
        return self.env.buffers.episode_count[: self.rows].cpu().numpy().copy()

    def _drawn(self, row: int) -> bool:
        return self.episodes_per_row is None or self._ended[row] < self.episodes_per_row

    def _log_resets(self, rows) -> None:
        """Rows reset since the last call: an episode the env did not end itself (the loop's step limit) is
        logged as stopped; every reset logs the start of the next episode."""
        for w in rows:
            if not self._drawn(w):
                continue
            if self._open[w] and self._frames[w] > 0:  # (a reset before any frame starts the first episode)
                self._ended[w] += 1
                self.rec.log(
                    f"events/{w}",
                    rr.TextLog(
                        f"row {w} episode {self._ended[w]} failed (stopped by the loop) after {self._frames[w]} steps",
                        level="WARN",
                    ),
                )
            self._open[w], self._frames[w] = True, 0
            if self._drawn(w):
                self.rec.log(
                    f"events/{w}", rr.TextLog(f"row {w} reset: episode {self._ended[w] + 1} starts", level="DEBUG")
                )

    def _log_ends(self, info) -> None:
        """``events/<row>``: an episode's end (success or failure, reason, length; episodes numbered from 1 per
        row in this recording)."""
        done = info["done"][: self.rows].cpu().numpy()
        success = info["success"][: self.rows].cpu().numpy()
        reason = info["termination_reason"][: self.rows].cpu().numpy()
        length = info["episode_length"][: self.rows].cpu().numpy()
        for w in np.nonzero(done)[0]:
            if not self._drawn(w):
                continue
            ok = bool(success[w])
            self._ended[w] += 1
            self._open[w] = False
            why = self.env.task.termination_reasons[int(reason[w])]
            self.rec.log(
                f"events/{w}",
                rr.TextLog(
                    f"row {w} episode {self._ended[w]} {'succeeded' if ok else 'failed'} ({why}) after "
                    f"{int(length[w])} steps",
                    level="INFO" if ok else "WARN",
                ),
            )

    def _camera_frames(self):
        """The env's current images and camera poses of the logged rows: ({camera: {data: (rows, ...)}},
        {camera: (rows, 7)})."""
        env, n = self.env, self.rows
        frames = {
            c.name: {d: env.sensors.images[f"{c.name}_{d}"][:n].cpu().numpy() for d in c.data} for c in self.cameras
        }
        return frames, {c.name: env.sensors.cameras.poses(c.name)[:n].cpu().numpy() for c in self.cameras}

    def log_step(
        self,
        *,
        reward=None,
        success=None,
        body_q: np.ndarray | None = None,
        info=None,
        camera_frames=None,
        camera_poses=None,
    ) -> None:
        """Log the current body poses of the first rows (or ``body_q`` given (rows * bodies, 7)), the TCP
        marker, per-row phase / reward / success scalars, the cameras (every ``image_every``-th step: the env's
        images, or ``camera_frames`` {camera: {data: (rows, ...)}} at ``camera_poses`` {camera: (rows, 7)}) and
        (with the step's ``info``) episode events at the next ``step`` time."""
        env = self.env
        self.rec.set_time("step", sequence=self._step)
        self.rec.set_time("sim_time", duration=self._step * env.cfg.control_dt)
        q = body_q if body_q is not None else env.state.body_q.numpy()[: self.rows * self._bpw]
        q = np.asarray(q)[: self.rows * self._bpw].reshape(self.rows, self._bpw, 7)
        tcp = env.buffers.tcp_pose[: self.rows, :3].cpu().numpy()
        done = info["done"][: self.rows].cpu().numpy() if info is not None else np.zeros(self.rows, dtype=bool)
        count = self._episode_count()
        reset = count != self._episodes  # this step's auto-resets (done) or the loop's resets since the last call
        self._episodes = count
        self._log_resets(np.nonzero(reset & ~done)[0])
        shoot = bool(self.cameras) and self._step % self.image_every == 0 and any(map(self._drawn, range(self.rows)))
        if shoot and camera_frames is None:
            camera_frames, camera_poses = self._camera_frames()
        for w in range(self.rows):
            if not self._drawn(w):
                continue
            self._frames[w] += 1
            for b in range(self._bpw):
                self.rec.log(
                    self.body_path(w, b),
                    rr.Transform3D(translation=q[w, b, :3], quaternion=rr.Quaternion(xyzw=q[w, b, 3:7])),
                )
            self.rec.log(f"world/{w}/tcp", rr.Points3D([tcp[w]], radii=[0.01], colors=[[255, 200, 0]]))
            for cam in self.cameras if shoot else ():
                log_camera_frame(
                    self.rec,
                    w,
                    cam,
                    camera_poses[cam.name][w],
                    {d: camera_frames[cam.name][d][w] for d in cam.data},
                    jpeg_quality=self.jpeg_quality,
                )
            self.rec.log(f"metrics/{w}/phase", rr.Scalars(float(env.info["phase"][w])))
            if reward is not None:
                self.rec.log(f"metrics/{w}/reward", rr.Scalars(float(reward[w])))
            if success is not None:
                self.rec.log(f"metrics/{w}/success", rr.Scalars(float(success[w])))
        if info is not None:
            self._log_ends(info)
        self._log_resets(np.nonzero(reset & done)[0])
        self._step += 1

    @property
    def finished(self) -> bool:
        """Every drawn row has shown its ``episodes_per_row`` episodes (never, without a limit)."""
        return not any(self._drawn(w) for w in range(self.rows))

    def on_step(self, reward, info) -> None:
        """The ``on_step(reward, info)`` hook of ``env.collect`` / ``env.evaluate``."""
        if self.finished:
            return
        self.log_step(reward=reward, success=info["success"], info=info)

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


def replay_episode(
    path,
    episode: int = 0,
    *,
    save: str | Path | None = None,
    spawn: bool = False,
    device: str | None = "cpu",
    jpeg_quality: int | None = None,
) -> np.ndarray:
    """Re-apply a recorded episode's states (robot joints, object poses) frame by frame on a one-row env of
    its task and log them to rerun, with the episode's recorded camera images (``obs/<camera>_rgb`` / ``_depth``
    / ``_segmentation``) on their pinholes (``datagen/camera_poses/<camera>``, else the mount's pose).
    Returns the replayed body poses (T, bodies, 7)."""
    info = read_dataset_info(path)
    ids = info["demo_ids"]
    if episode not in ids:
        raise ValueError(
            f"{path} has no episode {episode}; available: {ids[:5]}{'...' if len(ids) > 5 else ''} "
            f"({len(ids)} episodes)"
        )
    ep = read_episode(path, episode)
    env = make_env(  # images are recorded; the states hold the distractors' coordinates when there were any
        info["task_id"], num_envs=1, device=device, capture=False, cameras=False, **recorded_scene(info["env_args"])
    )
    obs = ep.get("obs", {})
    streams = dataset_streams(obs, info["env_args"], env.robot)
    cam_poses = ep.get("datagen", {}).get("camera_poses", {})
    logger = (
        RerunLogger(
            env,
            save=save,
            spawn=spawn,
            max_worlds=1,
            app_id="newton_lab_replay",
            cameras=streams,
            jpeg_quality=jpeg_quality,
        )
        if (save is not None or spawn)
        else None
    )
    states = state_tree(ep["states"], info["env_args"])  # flat (format 2) or nested (format 1)
    robot = states["articulation"]["robot"]["joint_position"]
    objects = states.get("rigid_object", {})
    q = wp.to_torch(env.state.joint_q).view(-1)
    poses = []
    for t in range(len(robot)):
        q[: robot.shape[1]] = torch.as_tensor(robot[t], dtype=torch.float32)
        for name, rec in objects.items():
            c = env.task.entities[name].coord
            q[c : c + 7] = torch.as_tensor(rec["root_pose"][t], dtype=torch.float32)
        newton.eval_fk(env.model, env.state.joint_q, env.state.joint_qd, env.state)
        body_q = env.state.body_q.numpy().copy()
        poses.append(body_q)
        if logger is not None:
            env.sim.observe()
            frames = {c.name: {d: np.asarray(obs[f"{c.name}_{d}"][t])[None] for d in c.data} for c in streams}
            at = {
                c.name: (
                    np.asarray(cam_poses[c.name][t])
                    if c.name in cam_poses
                    else mount_poses(env.model, body_q, c.name, env.robot)
                )[None]
                for c in streams
            }
            logger.log_step(body_q=body_q, camera_frames=frames, camera_poses=at)
    if logger is not None:
        logger.close()
    return np.stack(poses)
