"""Sequence windows over every demo of a dataset, held in memory, for diffusion-policy training.

One window per episode step t: observations of steps t-obs_horizon+1 .. t and actions of steps
t-obs_horizon+1 .. t-obs_horizon+pred_horizon. Steps before 0 repeat frame 0 (pad_before =
obs_horizon - 1); steps past the end repeat the last frame/action (pad_after = pred_horizon -
obs_horizon). Repeating the last action is right here: actions are absolute joint targets, so it
means "hold the final pose" (delta-action datasets would pad with zeros instead).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from newton_lab.datasets import read_dataset_info, read_episode, read_episodes

EXCLUDED_OBS_KEYS = ("actions",)  # the last-action obs term would leak the label
IMAGE_TAGS = ("rgb", "image", "depth", "camera")


def is_image_like(name: str, arr: np.ndarray) -> bool:
    """Images are left to a vision encoder: (T, H, W[, C]) arrays, uint8 arrays, or image-named keys."""
    return arr.ndim >= 3 or arr.dtype == np.uint8 or any(tag in name.lower() for tag in IMAGE_TAGS)


def default_obs_keys(obs: dict[str, Any], obs_terms: dict[str, Any] | None = None) -> list[str]:
    """Flat low-dim obs arrays except ``actions``, in env layout order (``obs_terms``) then by name."""
    order = {name: span[0] for name, span in (obs_terms or {}).items()}
    keys = [
        k
        for k, v in obs.items()
        if not isinstance(v, dict) and k not in EXCLUDED_OBS_KEYS and not is_image_like(k, np.asarray(v))
    ]
    return sorted(keys, key=lambda k: (k not in order, order.get(k, 0), k))


def _check_trained_together(infos: list[dict[str, Any]]) -> None:
    """Datasets trained together share the task and the action columns (one line naming the odd one)."""
    first = infos[0]
    for info in infos[1:]:
        names = [i["env_args"].get("newton_lab", {}).get("action_joint_names") for i in (first, info)]
        if info["task_id"] != first["task_id"] or names[0] != names[1]:
            raise ValueError(
                f"{info['path']} ({info['task_id']}) does not match {first['path']} ({first['task_id']}): "
                "datasets trained together need the same task and action columns"
            )


class SequenceDataset(Dataset):
    """``ds[i] -> {"obs": (obs_horizon, obs_dim), "actions": (pred_horizon, action_dim)}`` float32, raw units;
    with ``image_keys`` also ``"images": {key: (obs_horizon, H, W, 3)}`` uint8 (RGB frames, held in memory)."""

    def __init__(
        self,
        path: str | Path | Sequence[str | Path],
        *,
        obs_keys: Sequence[str] | None = None,
        obs_horizon: int = 2,
        pred_horizon: int = 16,
        success_only: bool = True,
        image_keys: Sequence[str] | None = None,
    ) -> None:
        if obs_horizon < 1 or pred_horizon < obs_horizon:
            raise ValueError(f"need 1 <= obs_horizon <= pred_horizon, got {obs_horizon} and {pred_horizon}")
        infos = [read_dataset_info(p) for p in ([path] if isinstance(path, (str, Path)) else path)]
        if not infos:
            raise ValueError("no dataset given; pass a dataset path or a list of them")
        self.paths: tuple[Path, ...] = tuple(Path(i["path"]) for i in infos)
        self.path = self.paths[0]
        self.task_id: str = infos[0]["task_id"]
        self.env_args: dict[str, Any] = infos[0]["env_args"]
        meta = self.env_args.get("newton_lab", {})
        _check_trained_together(infos)
        self.obs_horizon, self.pred_horizon = obs_horizon, pred_horizon
        self.demos: list[tuple[Path, int]] = [
            (Path(info["path"]), i)
            for info in infos
            for i in info["demo_ids"]
            if info["demos"][i]["success"] or not success_only
        ]
        self.demo_ids = [i for _, i in self.demos]  # ids within their file; ``demos`` pairs each with its file
        if not self.demos:
            total = sum(len(info["demo_ids"]) for info in infos)
            if total:
                raise ValueError(
                    f"{self.path} has no successful demos ({total} failed); pass success_only=False to train on them"
                )
            raise ValueError(f"{self.path} has no demos to train on")

        obs_rows, act_rows, obs_index, act_index, start = [], [], [], [], 0
        self.image_keys: tuple[str, ...] = tuple([image_keys] if isinstance(image_keys, str) else image_keys or ())
        frames: dict[str, list[np.ndarray]] = {k: [] for k in self.image_keys}
        self.obs_dims: dict[str, int] = {}
        first = read_episode(*self.demos[0]).get("obs", {})
        if isinstance(obs_keys, str):
            obs_keys = [obs_keys]
        keys = list(obs_keys) if obs_keys is not None else default_obs_keys(first, meta.get("obs_terms"))
        self.obs_keys: tuple[str, ...] = tuple(self._check_keys(keys, first, self.demos[0][1]))
        for file, demo, ep in self._episodes():
            obs = ep.get("obs", {})
            n = len(ep["actions"])
            if n == 0:
                continue
            parts = []
            for k in self.obs_keys:
                if k not in obs:
                    raise ValueError(f"demo {demo} of {file} has no obs/{k}")
                parts.append(np.asarray(obs[k], dtype=np.float32).reshape(n, -1))
            obs_rows.append(np.concatenate(parts, axis=1))
            for k in self.image_keys:
                frames[k].append(self._frames(obs, k, n, file, demo))
            act_rows.append(np.asarray(ep["actions"], dtype=np.float32))
            steps = np.arange(n)[:, None]
            obs_index.append(start + np.clip(steps + np.arange(-obs_horizon + 1, 1), 0, n - 1))
            act_steps = np.arange(-obs_horizon + 1, pred_horizon - obs_horizon + 1)
            act_index.append(start + np.clip(steps + act_steps, 0, n - 1))
            start += n
            if not self.obs_dims:
                self.obs_dims = {k: p.shape[1] for k, p in zip(self.obs_keys, parts)}
            elif [p.shape[1] for p in parts] != list(self.obs_dims.values()):
                raise ValueError(
                    f"demo {demo} of {file} has obs dims differing from demo {self.demo_ids[0]} of {self.path}"
                )
        self._stack(obs_rows, act_rows, frames, obs_index, act_index, meta.get("action_joint_names"))

    def _stack(self, obs_rows, act_rows, frames, obs_index, act_index, action_names) -> None:
        """The episodes' rows as one tensor per kind (observations, actions, each image key) and the windows'
        indices into them; refused when the demos disagree on sizes."""
        if not act_rows:
            raise ValueError(f"the selected demos of {self.path} hold no steps")
        try:
            self.obs = torch.from_numpy(np.concatenate(obs_rows))
            self.actions = torch.from_numpy(np.concatenate(act_rows))
        except ValueError:
            raise ValueError(f"demos of {self.path} have different action dims") from None
        try:
            self.images = {k: torch.from_numpy(np.concatenate(v)) for k, v in frames.items()}
        except ValueError:
            raise ValueError(f"demos of {self.path} have image frames of different sizes") from None
        self.image_shapes = {k: tuple(v.shape[1:]) for k, v in self.images.items()}
        """(H, W, C) of every image key."""
        self.obs_index = torch.from_numpy(np.concatenate(obs_index))
        self.action_index = torch.from_numpy(np.concatenate(act_index))
        names = action_names or [f"action_{i}" for i in range(self.action_dim)]
        if len(names) != self.action_dim:
            raise ValueError(f"{self.path}: {len(names)} action_joint_names but actions have {self.action_dim} columns")
        self.action_joint_names: tuple[str, ...] = tuple(names)

    def _episodes(self) -> Iterator[tuple[Path, int, dict[str, Any]]]:
        """(file, demo, episode) of every selected demo, holding only the actions and the trained obs terms: one
        open dataset per file (an episode missing one of them is read whole, for the error that names it)."""
        wanted = ("actions", *(f"obs/{k}" for k in (*self.obs_keys, *self.image_keys)))
        for file, group in itertools.groupby(self.demos, key=lambda fd: fd[0]):
            ids = [demo for _, demo in group]
            for demo, ep in zip(ids, read_episodes(file, ids, keys=wanted)):
                obs = ep.get("obs", {})
                if "actions" not in ep or any(k not in obs for k in (*self.obs_keys, *self.image_keys)):
                    ep = read_episode(file, demo)
                yield file, demo, ep

    def _frames(self, obs: dict[str, Any], key: str, n: int, file: Path, demo: int) -> np.ndarray:
        """(n, H, W, 3) uint8 RGB frames of ``obs/<key>``; one-line errors for what is not."""
        images = [k for k, v in obs.items() if not isinstance(v, dict) and np.asarray(v).ndim == 4]
        if key not in obs:
            raise ValueError(
                f"demo {demo} of {file} has no image obs/{key}; image terms there: "
                f"{', '.join(images) or 'none (collect with --cameras)'}"
            )
        arr = np.asarray(obs[key])
        if arr.dtype != np.uint8 or arr.ndim != 4 or arr.shape[0] != n or arr.shape[-1] != 3:
            raise ValueError(
                f"obs/{key} of demo {demo} in {file} is {arr.dtype} {arr.shape}; image keys must be "
                f"RGB frames (T, H, W, 3) uint8, e.g. front_head_rgb"
            )
        return arr

    def _check_keys(self, keys: list[str], obs: dict[str, Any], demo: int) -> list[str]:
        low_dim = [k for k, v in obs.items() if not isinstance(v, dict) and not is_image_like(k, np.asarray(v))]
        bad = [k for k in keys if k not in low_dim]
        if bad or not keys:
            raise ValueError(
                f"obs keys {bad or keys} are not low-dim obs arrays of demo {demo} in {self.path}; "
                f"available: {', '.join(low_dim) or 'none'}"
            )
        return keys

    @property
    def source(self) -> str:
        """The data as recorded in checkpoints and logs: the path, or the paths joined by ``", "``."""
        return ", ".join(str(p) for p in self.paths)

    @property
    def obs_dim(self) -> int:
        return self.obs.shape[1]

    @property
    def action_dim(self) -> int:
        return self.actions.shape[1]

    def __len__(self) -> int:
        return self.obs_index.shape[0]

    def __getitem__(self, i: int) -> dict[str, Any]:
        return self.windows().batch(torch.as_tensor(i))

    def __getitems__(self, indices: Sequence[int]) -> dict[str, Any]:
        """A whole batch by fancy indexing (DataLoader uses it; pair with ``collate_fn=collate_batch``)."""
        return self.windows().batch(torch.as_tensor(indices, dtype=torch.long))

    def windows(self, device: torch.device | str | None = None) -> Windows:
        """Every window's arrays, here or copied to ``device`` (the captured training step keeps them on the GPU,
        frames as uint8); both paths gather their batches with ``Windows.batch``."""
        w = Windows(self.obs, self.actions, self.images, self.obs_index, self.action_index)
        return w if device is None else w.to(device)

    def __repr__(self) -> str:
        return (
            f"SequenceDataset({self.source!r}, demos={len(self.demos)}, windows={len(self)}, "
            f"obs_keys={list(self.obs_keys)}, obs_dim={self.obs_dim}, action_dim={self.action_dim})"
        )


@dataclass(frozen=True)
class Windows:
    """The arrays batches are gathered from: low-dim obs (frames, obs_dim), actions (frames, action_dim), uint8
    images (frames, H, W, 3) per key, and per window its obs frames (windows, obs_horizon) and action frames
    (windows, pred_horizon)."""

    obs: torch.Tensor
    actions: torch.Tensor
    images: dict[str, torch.Tensor]
    obs_index: torch.Tensor
    action_index: torch.Tensor

    def to(self, device: torch.device | str) -> Windows:
        """The same arrays on ``device``."""
        return Windows(
            self.obs.to(device),
            self.actions.to(device),
            {k: v.to(device) for k, v in self.images.items()},
            self.obs_index.to(device),
            self.action_index.to(device),
        )

    def batch(self, idx: torch.Tensor) -> dict[str, Any]:
        """The windows ``idx`` (on this device): obs (B, obs_horizon, obs_dim), actions (B, pred_horizon,
        action_dim) and, with images, their frames (B, obs_horizon, H, W, 3) by key."""
        frames = self.obs_index[idx]
        out: dict[str, Any] = {"obs": self.obs[frames], "actions": self.actions[self.action_index[idx]]}
        if self.images:
            out["images"] = {k: v[frames] for k, v in self.images.items()}
        return out


def collate_batch(batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """DataLoader ``collate_fn`` for batches already built by ``SequenceDataset.__getitems__``."""
    return batch
