"""Episode columns: the per-step arrays of many recorded episodes side by side, one ``(rows, steps, width)`` float32
block, and the robomimic episode tree of one of them.

``collect``'s recorder (``envs.recorder``) stacks every row's frames as ``[frame | reward | next observation]``
along the last axis; ``ColumnLayout`` names where each array lies in it. It is plain data (picklable, no torch), so
the episode trees can be built where the episodes are written: in the collecting process (``EpisodeRecorder``) or
in a writer process of its own (``datasets.writer_process``), which takes that per-demo Python off the simulation's
interpreter.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._common import put


@dataclass(frozen=True)
class ColumnLayout:
    """Where each recorded array lies along the last axis of a column block."""

    frame: dict[str, tuple[int, int]]
    """Array key (``obs/<term>``, ``states/joint_q``, ``states/joint_qd``, ``datagen/...``, ``actions``) -> its
    ``(start, stop)`` in a frame."""
    frame_width: int
    """Floats of one frame; the step's reward follows at this index, then the next observation."""
    next_obs: dict[str, tuple[int, int]]
    """Observation term -> its ``(start, stop)`` in the next observation (``next_obs/<term>``)."""

    @property
    def width(self) -> int:
        """Floats per step of a block: frame, reward and next observation."""
        return self.frame_width + 1 + max((stop for _, stop in self.next_obs.values()), default=0)


def split(layout: ColumnLayout, block: np.ndarray) -> dict[str, np.ndarray]:
    """A host block ``(rows, steps, layout.width)`` split by array, each ``(rows, steps, width)`` and contiguous
    (``rewards``: ``(rows, steps)``): a writer joining hundreds of demos into a pack then copies whole blocks instead of
    strided column slices of every demo (512 PickCube demos on the CPU: 0.40 -> 0.28 ms a demo, noisy)."""
    after = layout.frame_width + 1  # next observations follow the frame and the reward
    columns = {key: np.ascontiguousarray(block[:, :, a:b]) for key, (a, b) in layout.frame.items()}
    columns["rewards"] = np.ascontiguousarray(block[:, :, layout.frame_width])
    columns.update({f"next_obs/{key}": np.ascontiguousarray(block[:, :, after + a: after + b])
                    for key, (a, b) in layout.next_obs.items()})
    return columns


def episode_tree(columns: dict[str, np.ndarray], images: dict[str, np.ndarray], length: int,
                 success: bool | None = None) -> dict[str, Any]:
    """One finished episode as a nested dict of numpy arrays (robomimic layout) from its rows of :func:`split`
    (``(steps, width)`` each, ``steps >= length``) and its image terms (``(steps, ...)`` each): ``actions``, ``obs/*``
    (image terms too: (T, H, W, 3) uint8 RGB, (T, H, W) float32 depth [m], (T, H, W) int32 segmentation),
    ``next_obs/*`` (the low-dim observation after each step), flat ``states`` (T, joint_q + joint_qd; named by
    ``env_args`` ``state_layout``), ``rewards`` (T,) the env's reward of each step, ``dones`` (T,) zeros, its last
    step ``success`` when given (robomimic marks a successful episode's end so), ``initial_state`` (1, D) and
    ``datagen/*`` (with cameras: ``camera_poses/<camera>`` (T, 7) world pose, xyz + quaternion xyzw, pinhole frame)."""
    flat = {key: arr[:length] for key, arr in columns.items()}
    states = np.concatenate([flat.pop("states/joint_q"), flat.pop("states/joint_qd")], axis=1)
    tree: dict[str, Any] = {"actions": flat.pop("actions"), "states": states, "obs": {}, "datagen": {},
                            "next_obs": {}, "rewards": flat.pop("rewards"), "dones": np.zeros(length, dtype=np.int64)}
    if success is not None and length:
        tree["dones"][-1] = int(success)
    for key, arr in flat.items():
        put(tree, key, arr)
    for name, img in images.items():
        tree["obs"][name] = np.asarray(img[:length])
    tree["datagen"]["subtask_signals"] = {
        k: v[:, 0].astype(bool) for k, v in tree["datagen"].get("subtask_signals", {}).items()
    }
    tree["datagen"]["phase"] = tree["datagen"]["phase"][:, 0].astype(np.int32)
    tree["initial_state"] = states[:1]
    return tree
