"""Recorded episodes as columns: ``collect``'s per-step arrays of many episodes side by side, and the robomimic episode
trees they make.

``collect``'s recorder (``envs.recorder``) stacks every row's frames as ``[frame | reward | next observation]``
along the last axis of one ``(rows, steps, width)`` float32 block; ``ColumnLayout`` names where each array lies in
it. A ``DemoBlock`` holds finished episodes of such a block split into their arrays, each joined along time (each
demo's steps after the last one's): every array of a whole batch of demos is one array, which is what a zarr pack stores
(``zarr.packs``), so a writer can pack a batch without building, checking and re-joining one tree per demo. Both
are plain numpy (picklable, no torch): the same code serves the collecting process and a writer process of its own
(``datasets.writers.process``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..files.layout import put
from ..files.row_pieces import RowPieces

STATES = ("states/joint_q", "states/joint_qd")
"""Frame arrays joined side by side into a demo's flat ``states`` (joint_q then joint_qd)."""


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


@dataclass
class DemoBlock:
    """Finished episodes joined along time: each array of ``columns`` (by its path in an episode tree: ``actions``,
    ``obs/<term>`` image terms included, ``states``, ``rewards``, ``next_obs/<term>``, ``datagen/...``) holds demo
    0's steps, then demo 1's, ...; per demo its length, success and attrs."""

    columns: dict[str, np.ndarray]
    lengths: list[int]
    successes: list[bool]
    attrs: list[dict[str, Any]]

    @classmethod
    def from_rows(
        cls,
        layout: ColumnLayout,
        stacked: np.ndarray,
        images: dict[str, np.ndarray],
        demos: list[tuple[int, int, bool | None, dict[str, Any]]],
        *,
        image_views: bool = False,
    ) -> DemoBlock:
        """The demos ``(row, length, success, attrs)`` of a ``(rows, steps, width)`` block and its image terms
        ``(rows, steps, ...)``, copied out (one gather per array: the block may be reused at once) and split into
        their arrays here, while the burst is small: splitting a joined batch of thousands of demos instead reads
        all of it once per array, out of cache (the writer's largest cost at 4096 rows). With ``image_views`` the
        image terms are not copied: each is a ``RowPieces`` of every demo's rows of ``images`` (the caller keeps
        ``images`` as they are until the block is written)."""
        rows = np.asarray([row for row, _, _, _ in demos], dtype=np.int64)
        lengths = [int(length) for _, length, _, _ in demos]
        span = stacked.shape[1]
        inside = np.arange(span)[None, :] < np.asarray(lengths, dtype=np.int64)[:, None]  # (demos, span)
        whole = len(rows) == stacked.shape[0] and bool((rows == np.arange(len(rows))).all())

        def gather(arr: np.ndarray) -> np.ndarray:
            return (arr if whole else arr[rows])[inside]

        f = gather(stacked)
        out = {key: np.ascontiguousarray(f[:, a:b]) for key, (a, b) in layout.frame.items() if key not in STATES}
        out["states"] = np.concatenate([f[:, slice(*layout.frame[key])] for key in STATES], axis=1)
        out["rewards"] = np.ascontiguousarray(f[:, layout.frame_width])
        after = layout.frame_width + 1
        out.update(
            {
                f"next_obs/{key}": np.ascontiguousarray(f[:, after + a : after + b])
                for key, (a, b) in layout.next_obs.items()
            }
        )
        for key in [k for k in out if k.startswith("datagen/subtask_signals/")]:
            out[key] = out[key][:, 0].astype(bool)
        out["datagen/phase"] = out["datagen/phase"][:, 0].astype(np.int32)
        if image_views:
            out.update(
                {
                    f"obs/{name}": RowPieces([img[row, :length] for row, length in zip(rows.tolist(), lengths)])
                    for name, img in images.items()
                }
            )
        else:
            out.update({f"obs/{name}": gather(img) for name, img in images.items()})
        return cls(out, lengths, [s for _, _, s, _ in demos], [dict(a) for _, _, _, a in demos])

    @classmethod
    def join(cls, blocks: list[DemoBlock]) -> DemoBlock:
        """One block of the demos of ``blocks``, in order."""
        if len(blocks) == 1:
            return blocks[0]
        return cls(
            {key: _join([b.columns[key] for b in blocks]) for key in blocks[0].columns},
            [n for b in blocks for n in b.lengths],
            [s for b in blocks for s in b.successes],
            [a for b in blocks for a in b.attrs],
        )

    def __len__(self) -> int:
        return len(self.lengths)

    @property
    def nbytes(self) -> int:
        """Bytes of every column (image frames held as views too)."""
        return sum(arr.nbytes for arr in self.columns.values())

    @property
    def starts(self) -> np.ndarray:
        """Each demo's first row in the joined arrays."""
        return np.concatenate([[0], np.cumsum(self.lengths[:-1], dtype=np.int64)]).astype(np.int64)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every array of the demos, joined, by its path in an episode tree (see :meth:`trees`): ``columns``, then
        ``dones`` and ``initial_state`` (one row per demo)."""
        out = dict(self.columns)
        dones = np.zeros(sum(self.lengths), dtype=np.int64)
        ends = self.starts + np.asarray(self.lengths, dtype=np.int64) - 1
        for end, success in zip(ends.tolist(), self.successes):
            if success is not None and end >= 0:
                dones[end] = int(success)
        out["dones"] = dones
        out["initial_state"] = out["states"][self.starts]
        return out

    def trees(self) -> list[dict[str, Any]]:
        """One nested dict of numpy arrays per demo (robomimic layout; views of one joined copy): ``actions``,
        ``obs/*`` (image terms too: (T, H, W, 3) uint8 RGB, (T, H, W) float32 depth [m], (T, H, W) int32
        segmentation), ``next_obs/*`` (the low-dim observation after each step), flat ``states`` (T, joint_q +
        joint_qd; named by ``env_args`` ``state_layout``), ``rewards`` (T,) the env's reward of each step, ``dones``
        (T,) zeros, the last step 1 for a success (robomimic's mark; a demo whose success is None keeps 0),
        ``initial_state`` (1, D) and ``datagen/*`` (``subtask_signals/<name>`` (T,) bool, ``phase`` (T,) int32; with
        cameras ``camera_poses/<camera>`` (T, 7) world pose, xyz + quaternion xyzw, pinhole frame)."""
        arrays = self.arrays()
        initial = arrays.pop("initial_state")
        out = []
        for k, (start, length) in enumerate(zip(self.starts.tolist(), self.lengths)):
            tree: dict[str, Any] = {"obs": {}, "datagen": {"subtask_signals": {}}, "next_obs": {}}
            for key, arr in arrays.items():
                put(tree, key, arr[start : start + length])
            tree["initial_state"] = initial[k : k + 1]
            out.append(tree)
        return out

    def pack_layout(self, arrays: dict[str, np.ndarray]) -> dict[str, int | None] | None:
        """The zarr pack index's ``arrays`` for :meth:`arrays` (what ``zarr.packs.layout`` makes of the demos'
        trees: None per step, 1 for ``initial_state``), or None where a tree holds an empty group (a task without
        subtask signals), which a pack cannot hold."""
        if not any(key.startswith("datagen/subtask_signals/") for key in arrays) or not any(
            key.startswith("next_obs/") for key in arrays
        ):
            return None
        every_step = all(n == 1 for n in self.lengths)  # then initial_state has as many rows as the demo has steps
        return {key: (None if key != "initial_state" or every_step else 1) for key in arrays}


def _join(arrays: list) -> np.ndarray | RowPieces:
    """Arrays joined along time: image views stay views (``RowPieces``), numpy arrays are concatenated."""
    if isinstance(arrays[0], RowPieces):
        return RowPieces.join(arrays)
    return np.concatenate(arrays)
