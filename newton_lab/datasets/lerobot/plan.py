"""What a LeRobot export writes, decided before its first byte: the frame rate, the demos kept, the state, action
and image features (``Plan``), and each episode's arrays in that layout."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..storage import read_episode
from .tables import IMAGE_NAMES, IMAGE_PREFIX, INDEX_FEATURES
from .video import even_shape, video_info


@dataclass
class Plan:
    """Everything decided before the first byte is written."""

    source: Path
    source_format: str
    task_id: str
    repo_id: str
    task: str
    fps: int
    demo_ids: list[int]
    skipped_failed: list[int]
    skipped_empty: list[int]
    state_terms: list[tuple[str, int]]  # (obs term, width), in state column order
    action_dim: int
    action_names: list[str]
    image_terms: list[tuple[str, tuple[int, int, int]]]  # (obs term, (H, W, 3))
    ignored_terms: list[str] = field(default_factory=list)
    video: bool = True  # image terms as mp4 "video" features (else PNG "image" features in the data files)

    @property
    def state_dim(self) -> int:
        return sum(w for _, w in self.state_terms)

    def features(self) -> dict[str, dict[str, Any]]:
        feats: dict[str, dict[str, Any]] = {
            "observation.state": {
                "dtype": "float32",
                "shape": [self.state_dim],
                "names": [f"{t}.{i}" for t, w in self.state_terms for i in range(w)],
            },
            "action": {"dtype": "float32", "shape": [self.action_dim], "names": list(self.action_names)},
        }
        for term, shape in self.image_terms:
            feats[IMAGE_PREFIX + term] = (
                {
                    "dtype": "video",
                    "shape": list(even_shape(shape)),
                    "names": list(IMAGE_NAMES),
                    "info": video_info(shape, self.fps),
                }
                if self.video
                else {"dtype": "image", "shape": list(shape), "names": list(IMAGE_NAMES)}
            )
        for key, dtype in INDEX_FEATURES.items():
            feats[key] = {"dtype": dtype, "shape": [1], "names": None}
        return feats


def _resolve_fps(fps: Any, nl: Mapping[str, Any], source: Path) -> int:
    if fps is None:
        try:
            period = float(nl["sim_dt"]) * int(nl["decimation"])
            value: Any = 1.0 / period
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            raise ValueError(
                f"{source} has no usable env_args['newton_lab'] sim_dt/decimation to derive the "
                "frame rate from; pass fps=<int>"
            ) from None
        what = f"the control rate 1/(sim_dt*decimation) = {value:.6g} Hz of {source}"
    else:
        value, what = fps, f"fps={fps!r}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{what} is not a number; pass fps=<positive int>")
    value = float(value)
    if not math.isfinite(value) or round(value) < 1 or abs(value - round(value)) > 1e-6 * round(value):
        raise ValueError(f"{what} is not a positive whole number; LeRobot needs an integer fps: pass fps=<int>")
    return int(round(value))


def _text(value: Any, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{name} must be a non-empty str, got {value!r}")
    return value


def _obs_kind(arr: np.ndarray) -> str:
    if arr.ndim == 4 and arr.shape[-1] == 3 and arr.dtype == np.uint8:
        return "image"
    if arr.ndim in (1, 2) and arr.dtype.kind in "biuf":
        return "vector"
    return "other"


def _obs_order(nl: Mapping[str, Any], present: Iterable[str]) -> list[str]:
    """Obs terms in the env's column order (env_args obs_terms starts), then any others by name."""
    declared = nl.get("obs_terms") if isinstance(nl.get("obs_terms"), Mapping) else {}

    def start(name: str) -> float:
        span = declared.get(name)
        try:
            return float(span[0])
        except (TypeError, ValueError, IndexError, KeyError):
            return math.inf

    present = list(present)
    known = sorted((t for t in present if t in declared), key=lambda t: (start(t), t))
    return known + sorted(t for t in present if t not in declared)


def make_plan(
    info: dict[str, Any], *, repo_id, fps, include_failed, state_keys, task_description
) -> tuple[Plan, dict[str, Any]]:
    source, task_id = Path(info["path"]), info["task_id"]
    nl = info["env_args"].get("newton_lab")
    nl = nl if isinstance(nl, Mapping) else {}
    fps_i = _resolve_fps(fps, nl, source)
    repo = _text(repo_id, "repo_id") if repo_id is not None else f"newton_lab/{task_id.lower()}"
    task = _text(task_description, "task_description") if task_description is not None else task_id
    if state_keys is not None and (isinstance(state_keys, (str, bytes)) or not isinstance(state_keys, Iterable)):
        raise TypeError(f"state_keys must be a list of obs term names, got {state_keys!r}")

    demos = info["demos"]
    failed = [i for i, d in demos.items() if not d["success"]]
    candidates = [i for i, d in demos.items() if include_failed or d["success"]]
    empty = [i for i in candidates if demos[i]["num_samples"] < 1]
    chosen = [i for i in candidates if demos[i]["num_samples"] >= 1]
    if not chosen:
        hint = "" if include_failed or not failed else " (pass include_failed=True to export the failed ones)"
        raise ValueError(
            f"{source} has no episodes to export: {len(demos)} demos, {len(failed)} failed, {len(empty)} empty{hint}"
        )

    first = read_episode(source, chosen[0])
    obs = {k: np.asarray(v) for k, v in first.get("obs", {}).items() if not isinstance(v, Mapping)}
    kinds = {k: _obs_kind(v) for k, v in obs.items()}
    order = _obs_order(nl, obs)
    where = f"demo_{chosen[0]} of {source}"
    if state_keys is None:
        state = [t for t in order if kinds[t] == "vector" and t != "actions"]
        if not state:
            raise ValueError(f"{where} has no (T, d) obs term for observation.state; pass state_keys=[...]")
    else:
        state = [str(t) for t in state_keys]
        if not state:
            raise ValueError("state_keys is empty; name at least one obs term")
        if len(set(state)) != len(state):
            raise ValueError(f"state_keys has duplicates: {state}")
        for t in state:
            if t not in obs:
                raise ValueError(f"state_keys: no obs term {t!r} in {where}; available: {', '.join(order) or 'none'}")
            if kinds[t] == "image":
                raise ValueError(
                    f"state_keys: {t!r} is an image term (exported as {IMAGE_PREFIX}{t}), not a (T, d) state term"
                )
            if kinds[t] != "vector":
                raise ValueError(
                    f"state_keys: obs term {t!r} has shape {obs[t].shape} dtype {obs[t].dtype}, not a real (T, d) array"
                )
    actions = np.asarray(first["actions"])
    a_dim = int(actions.shape[1])
    names = nl.get("action_joint_names")
    if not (isinstance(names, list) and len(names) == a_dim and all(isinstance(n, str) for n in names)):
        names = [f"action.{i}" for i in range(a_dim)]
    images = [(t, tuple(int(s) for s in obs[t].shape[1:])) for t in order if kinds[t] == "image"]
    ignored = [t for t in order if kinds[t] == "other" or (kinds[t] == "vector" and t not in state)]
    plan = Plan(
        source=source,
        source_format=info["format"],
        task_id=task_id,
        repo_id=repo,
        task=task,
        fps=fps_i,
        demo_ids=chosen,
        skipped_failed=[] if include_failed else failed,
        skipped_empty=empty,
        state_terms=[(t, 1 if obs[t].ndim == 1 else int(obs[t].shape[1])) for t in state],
        action_dim=a_dim,
        action_names=list(names),
        image_terms=images,
        ignored_terms=ignored,
    )
    return plan, first


def episode_arrays(ep: Mapping[str, Any], plan: Plan, demo_id: int) -> tuple[np.ndarray, np.ndarray, dict]:
    where = f"demo_{demo_id} of {plan.source}"
    actions = np.asarray(ep["actions"])
    if actions.ndim != 2 or actions.shape[1] != plan.action_dim:
        raise ValueError(
            f"{where}: actions have shape {actions.shape}; expected (T, {plan.action_dim}) like demo_{plan.demo_ids[0]}"
        )
    steps = actions.shape[0]
    obs = ep.get("obs", {})
    parts = []
    for term, width in plan.state_terms:
        if term not in obs or isinstance(obs[term], Mapping):
            raise ValueError(f"{where} has no obs term {term!r} (needed for observation.state)")
        arr = np.asarray(obs[term])
        arr = arr.reshape(-1, 1) if arr.ndim == 1 else arr
        if arr.ndim != 2 or arr.shape != (steps, width):
            raise ValueError(f"{where}: obs term {term!r} has shape {arr.shape}; expected ({steps}, {width})")
        parts.append(arr.astype(np.float32, copy=False))
    images = {}
    for term, shape in plan.image_terms:
        arr = np.asarray(obs.get(term)) if term in obs else None
        if arr is None or arr.dtype != np.uint8 or arr.shape != (steps, *shape):
            got = "missing" if arr is None else f"{arr.dtype} {arr.shape}"
            raise ValueError(f"{where}: image obs term {term!r} is {got}; expected uint8 {(steps, *shape)}")
        images[term] = arr
    state = np.ascontiguousarray(np.concatenate(parts, axis=1), dtype=np.float32)
    return state, np.ascontiguousarray(actions, dtype=np.float32), images
