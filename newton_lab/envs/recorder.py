"""Per-row episode buffers of ``collect`` (``EpisodeRecorder``) and the dataset's ``env_args`` record.

Image terms (``env.sensors.image_terms``) are recorded only when the env has them: each recorded step reads
``env.sensors.images`` (which renders, once, through the captured render) and copies every term into per-row device
frames that grow along time in chunks (``envs.frame_chunks``). A full-length buffer would be (N, max_steps, H, W,
3): at 298x224 RGB and max_steps 1000 that is 200 MB per row, 800 GB at 4096 rows; in chunks it holds N x (longest
running episode, rounded up to a chunk) frames, e.g. 38 MB per row (192 steps) for PickCube's ~170-step expert
episodes at 298x224. Staging frames on the host instead would add a device->host copy of every row's images to
every step (the simulation would wait for it); the device chunks keep the step on the device and copy only finished
episodes (``episodes``), together with their other arrays.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import torch
import warp as wp

from ..datasets.states import state_layout
from ..datasets.writers.columns import ColumnLayout, DemoBlock
from ..tasks.common.distractors import distractor_count
from .frame_chunks import FrameChunks


class EpisodeRecorder:
    """Per-row device buffers holding each running episode's frames: the observation and full state
    before the step, the action taken, and the Mimic datagen signals (TCP / object poses, subtask
    signals, phase); with cameras also every image term and each camera's pose (``datagen/camera_poses``)."""

    def __init__(self, env, max_steps: int):
        self.env = env
        self.max_steps = max_steps
        n = env.num_envs
        q = wp.to_torch(env.state.joint_q).view(n, -1)
        qd = wp.to_torch(env.state.joint_qd).view(n, -1)
        self._views: dict[str, torch.Tensor] = {}
        for name, sl in env.task.obs_terms.items():
            self._views[f"obs/{name}"] = env.obs[:, sl]
        self._views["states/joint_q"] = q
        self._views["states/joint_qd"] = qd
        self._views["datagen/tcp_pose"] = env.buffers.tcp_pose
        for name, e in env.task.entities.items():
            self._views[f"datagen/object_poses/{name}"] = env.buffers.entity_poses[:, e.slot]
        for k, name in enumerate(env.task.signal_names):
            self._views[f"datagen/subtask_signals/{name}"] = env.info["signals"][:, k : k + 1]
        self._views["datagen/phase"] = env.info["phase"].view(n, 1)
        self.image_terms = dict(env.sensors.image_terms)
        """Image term name -> ``envs.cameras.ImageTerm`` recorded each step (empty: nothing is rendered)."""
        if self.image_terms:
            env.render()  # builds the cameras: their pose buffers are fixed views from here on
            for cam in env.sensors.camera_specs:
                self._views[f"datagen/camera_poses/{cam}"] = env.sensors.cameras.poses(cam)
        frame: dict[str, tuple[int, int]] = {}
        col = 0
        for key, v in self._views.items():
            frame[key] = (col, col + v.shape[1])
            col += v.shape[1]
        frame["actions"] = (col, col + env.action_dim)
        col += env.action_dim
        self.layout = ColumnLayout(frame, col, {k: (sl.start, sl.stop) for k, sl in env.task.obs_terms.items()})
        """Where each array lies in a row of :meth:`fetch`'s ``stacked`` block."""
        self._frames = torch.zeros(n, max_steps, col, device=env.torch_device)
        self._rewards = torch.zeros(n, max_steps, device=env.torch_device)
        self._next_obs = torch.zeros(n, max_steps, env.buffers.final_obs.shape[1], device=env.torch_device)
        self._rows = torch.arange(n, device=env.torch_device)
        self._images = {
            name: FrameChunks(name, n, term.shape, term.dtype, env.torch_device)
            for name, term in self.image_terms.items()
        }

    def record(self, t: torch.Tensor, actions: torch.Tensor) -> None:
        """Store the pre-step frame of every row at its episode step ``t`` (N,)."""
        t = t.clamp(max=self.max_steps - 1)
        if self._images:
            images = self.env.render()  # first: the camera poses in the frame are those of this render
            first, last = torch.stack((t.min(), t.max())).tolist()  # one sync: the chunks the rows are in
            for name, frames in self._images.items():
                frames.grow(last)
                frames.write(t, images[name], first, last)
        frame = torch.cat([v.float() for v in self._views.values()] + [actions], dim=1)
        self._frames[self._rows, t] = frame

    def record_outcome(self, t: torch.Tensor, reward: torch.Tensor) -> None:
        """Store every row's reward of the step taken at its episode step ``t`` (N,) and the observation of the
        state it reached (``env.buffers.final_obs``: before an automatic reset)."""
        t = t.clamp(max=self.max_steps - 1)
        self._rewards[self._rows, t] = reward.float()
        self._next_obs[self._rows, t] = self.env.buffers.final_obs.float()

    def fetch(self, rows, lengths) -> FetchedRows:
        """The finished episodes of ``rows`` (``lengths`` steps each), still on the env's device: one gather of every
        buffer, and whether every recorded float of each row's steps (frames, rewards, next observations; images
        aside) is finite, checked for all rows in one pass (free on a GPU)."""
        rows, lengths = [int(r) for r in rows], [int(t) for t in lengths]
        span, idx = max(lengths), torch.as_tensor(rows, device=self._frames.device)
        stacked = self._stacked(idx, span)
        steps = torch.arange(span, device=idx.device)
        past_end = steps[None, :] >= torch.as_tensor(lengths, device=idx.device)[:, None]  # after each episode's end
        ok = (torch.isfinite(stacked).all(dim=2) | past_end).all(dim=1)
        images = {name: frames.gather(idx, span) for name, frames in self._images.items()}
        return FetchedRows(rows, lengths, stacked, images, dict(zip(rows, ok.tolist())))

    def episodes(self, rows, lengths) -> tuple[dict[int, dict[str, Any]], dict[int, bool]]:
        """The finished episodes of ``rows`` (``lengths`` steps each) with one device->host copy of their
        buffers (and one per image term): row -> :meth:`episode`, and row -> whether every recorded float of its
        steps is finite (:meth:`fetch`). The trees are views of one host copy joined by array
        (``datasets.writers.columns.DemoBlock``): each episode's arrays are contiguous, so a writer joining hundreds of
        demos into a pack copies whole blocks instead of strided column slices of every demo (512 PickCube demos on the
        CPU: 0.40 -> 0.28 ms a demo, noisy)."""
        got = self.fetch(rows, lengths)
        block = DemoBlock.from_rows(
            self.layout,
            got.stacked.cpu().numpy(),
            {name: img.cpu().numpy() for name, img in got.images.items()},
            [(k, t, None, {}) for k, t in enumerate(got.lengths)],
        )
        return dict(zip(got.rows, block.trees())), got.finite

    def _stacked(self, idx: torch.Tensor, span: int) -> torch.Tensor:
        """(rows, span, frame + reward + next observation) of the rows ``idx``: one gather of every buffer."""
        return torch.cat((self._frames[idx, :span], self._rewards[idx, :span, None], self._next_obs[idx, :span]), dim=2)

    def episode(self, row: int, length: int) -> dict[str, Any]:
        """The finished episode of ``row`` as a nested dict of numpy arrays
        (``datasets.writers.columns.DemoBlock.trees`` says what it holds); copies, never views of the live buffers (the
        row's next episode reuses them)."""
        return self.episodes([row], [length])[0][row]


class FetchedRows(NamedTuple):
    """Finished episodes gathered on the env's device by :meth:`EpisodeRecorder.fetch`."""

    rows: list[int]
    lengths: list[int]
    stacked: torch.Tensor
    """(rows, longest, ``layout.width``) float32: frames, rewards and next observations
    (``datasets.writers.columns``)."""
    images: dict[str, torch.Tensor]
    """Image term -> (rows, longest, ...)."""
    finite: dict[int, bool]
    """Row -> every recorded float of its steps is finite (images aside)."""


def camera_args(env) -> dict[str, Any]:
    """The ``env_args["newton_lab"]["cameras"]`` record: per rendered camera its resolution [px], data,
    3x3 intrinsics [px] and the segmentation id names (empty without cameras)."""
    specs = env.sensors.camera_specs
    if not specs:
        return {}
    names = list(env.sensors.cameras.segmentation_names)
    return {
        cam: {
            "width": c.width,
            "height": c.height,
            "data": list(c.data),
            "intrinsics": env.sensors.cameras.intrinsics(cam).tolist(),
            "segmentation_names": names,
        }
        for cam, c in specs.items()
    }


def recorded_scene(env_args: dict[str, Any]) -> dict[str, int]:
    """What the env that made a dataset was built with besides its task (``env_args(env)``): ``make_env`` keywords,
    ``{"distractors": n}`` (0 for a dataset recorded before the count was)."""
    return {"distractors": int((env_args.get("env_kwargs") or {}).get("distractors") or 0)}


def env_args(env) -> dict[str, Any]:
    """The ``data.attrs['env_args']`` record: enough to rebuild the env that made a dataset."""
    lay, n = env.sim.layout, env.num_envs
    q, qd = wp.to_torch(env.state.joint_q).view(n, -1), wp.to_torch(env.state.joint_qd).view(n, -1)
    return {
        "env_name": env.task_id,
        "type": 2,
        "env_kwargs": {
            "num_envs": env.num_envs,
            "seed": env.seed,
            "randomize": env.task.randomize,
            "task_options": env.cfg.options,
            "distractors": distractor_count(env.cfg),
        },
        "newton_lab": {
            "robot": env.robot.name,
            "sim_dt": env.cfg.sim_dt,
            "decimation": env.cfg.decimation,
            "action_joint_names": list(env.action_joint_names),
            "obs_terms": {k: [s.start, s.stop] for k, s in env.task.obs_terms.items()},
            "entities": list(env.task.entities),
            "signals": list(env.task.signal_names),
            "termination_reasons": list(env.task.termination_reasons),
            "phases": [ph.name for ph in env.cfg.phases],  # a coherent task's, in order (datagen/phase indexes them)
            "phase_kinds": list(env.cfg.phase_kinds) if env.cfg.phases else [],  # what the split writes
            "state_layout": state_layout(
                q.shape[1],
                qd.shape[1],
                lay.robot_coords,
                lay.robot_dofs,
                {
                    name: (lay.entity_coord[e.slot], lay.entity_dof[e.slot])
                    for name, e in env.task.entities.items()
                    if e.dynamic
                },
            ),
            "cameras": camera_args(env),
        },
    }
