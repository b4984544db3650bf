"""Which cameras an env renders: the task's views on its robot's mounts (``TaskCfg.cameras``), changed by a
``make_env(..., cameras=...)`` request (a dict or the CLI's text), checked; and the image observation terms
they give (``<camera>_<data>``: RGB uint8 (H, W, 3), depth float32 (H, W) [m], segmentation int32 (H, W)).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import newton
import numpy as np
import torch

from ..robots.binding import RobotBinding
from ..robots.registry import robot_binding
from ..task_api.cfg import IMAGE_DATA, CameraCfg, TaskCfg, camera_option


@dataclass(frozen=True)
class ImageTerm:
    """One image observation: ``<camera>_<data>``, per-row ``shape`` and torch ``dtype``."""

    name: str
    camera: str
    data: str
    shape: tuple[int, ...]
    dtype: torch.dtype


def _resolution(name: str, value: Any, sides: tuple[int, int]) -> tuple[int, int]:
    lo, hi = sides
    ok = (
        isinstance(value, (tuple, list))
        and len(value) == 2
        and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in value)
        and all(lo <= v <= hi for v in value)
    )
    if not ok:
        raise ValueError(
            f"camera {name!r} resolution must be (width, height) integers in [{lo}, {hi}] px, got "
            f"{value!r}; e.g. cameras={{'{name}': (96, 72)}}"
        )
    return int(value[0]), int(value[1])


def _data(name: str, value: Any) -> tuple[str, ...]:
    data = (value,) if isinstance(value, str) else tuple(value)
    bad = [d for d in data if d not in IMAGE_DATA]
    if not data or bad or len(set(data)) != len(data):
        raise ValueError(f"camera {name!r} data must be distinct entries of {list(IMAGE_DATA)}, got {value!r}")
    return data


def _override(name: str, base: CameraCfg, value: Any, sides: tuple[int, int]) -> CameraCfg:
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - {"resolution", "data"})
        if unknown:
            raise ValueError(f"camera {name!r} override has unknown keys {unknown}; use 'resolution' and/or 'data'")
        w, h = _resolution(name, value.get("resolution", (base.width, base.height)), sides)
        return CameraCfg(width=w, height=h, data=_data(name, value.get("data", base.data)))
    w, h = _resolution(name, value, sides)
    return CameraCfg(width=w, height=h, data=base.data)


def resolve_cameras(
    cfg: TaskCfg, cameras: bool | Mapping[str, Any] | str | None, *, robot: RobotBinding | None = None
) -> dict[str, CameraCfg]:
    """The cameras an env renders: the task's (``None`` or ``True``), none (``False``), or the task's changed by
    ``{mount: (width, height)}`` / ``{mount: {"resolution": (w, h), "data": (...)}}`` (a mount of the robot that the
    task does not declare is added, so a state-only task such as StackCube renders the cameras it is asked for), or
    any of these as the CLI's text (``"none"``, ``"front_head=96x72:rgb"``).
    ``robot``: the task's (``robot_binding(cfg.robot)``) when ``None``. Raises a one-line ``ValueError`` on an
    unknown mount, a bad resolution or data."""
    robot = robot_binding(cfg.robot) if robot is None else robot
    mounts, sides = list(robot.camera_mounts), robot.camera_resolution
    if isinstance(cameras, str):
        cameras = camera_option(cameras)
    if cameras is None or cameras is True:
        chosen = dict(cfg.cameras)
    elif cameras is False:
        return {}
    elif isinstance(cameras, Mapping):
        chosen = dict(cfg.cameras)
        for name, value in cameras.items():
            if name not in mounts:
                raise ValueError(f"unknown camera {name!r}; the {robot.name}'s cameras are {mounts}")
            chosen[name] = _override(name, chosen.get(name, CameraCfg()), value, sides)
    else:
        raise ValueError(
            f"cameras must be None, True, False, a dict {{camera: (width, height)}} or its text form, got {cameras!r}"
        )
    for name, cam in chosen.items():
        if name not in mounts:
            raise ValueError(f"{cfg.task_id} declares unknown camera {name!r}; the {robot.name}'s are {mounts}")
        _resolution(name, (cam.width, cam.height), sides)
        _data(name, cam.data)
    return chosen


def image_terms(specs: Mapping[str, CameraCfg]) -> dict[str, ImageTerm]:
    """The image observations of ``specs``, in camera then ``IMAGE_DATA`` order."""
    out = {}
    for cam, c in specs.items():
        for data in IMAGE_DATA:
            if data in c.data:
                shape = (c.height, c.width, 3) if data == "rgb" else (c.height, c.width)
                dtype = {"rgb": torch.uint8, "depth": torch.float32, "segmentation": torch.int32}[data]
                out[f"{cam}_{data}"] = ImageTerm(f"{cam}_{data}", cam, data, shape, dtype)
    return out


BACKGROUND, GROUND = "background", "ground"


def segmentation_table(
    model: newton.Model, entity_names: list[str], robot: RobotBinding
) -> tuple[tuple[str, ...], np.ndarray]:
    """(names, shape_to_id): id 0 ``background`` (nothing hit), 1 ``ground``, then the task's objects in slot
    order, then the robot's link groups (``robot/<group>``, ``RobotBinding.link_groups``); and the id of every
    shape of the model."""
    names = [BACKGROUND, GROUND, *entity_names, *robot.link_groups]
    ids = {n: i for i, n in enumerate(names)}
    world = model.shape_world.numpy()
    body = model.shape_body.numpy()
    table = np.zeros(model.shape_count, dtype=np.int32)
    for s in range(model.shape_count):
        label = model.shape_label[s].rsplit("/", 1)[-1]
        if world[s] < 0:
            table[s] = ids[GROUND]
        elif label in entity_names:
            table[s] = ids[label]
        elif body[s] >= 0:
            table[s] = ids[robot.link_group(model.body_label[body[s]].rsplit("/", 1)[-1])]
    return tuple(names), table
