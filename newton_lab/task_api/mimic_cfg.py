"""Mimic configuration, declared per task in its package (``tasks/<task>/config/g1/mimic_cfg.py``)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class SubtaskCfg:
    """One subtask of the source demos."""

    object_ref: str | None
    """Entity whose frame the segment is replayed in (``None``: world frame, no transform)."""
    term_signal: str | None
    """Recorded subtask signal whose first 0 -> 1 edge ends the subtask; ``None`` for the last one."""
    term_offset_range: tuple[int, int] = (0, 0)
    """Random offset [steps] added to the end index of each source segment (inclusive range)."""
    action_noise: float = 0.005
    """Std of Gaussian noise added to the arm joint targets [rad] (not during interpolation)."""
    num_interpolation_steps: int = 15
    """Steps interpolating from the last target pose to the transformed segment's first pose."""
    nn_k: int = 3
    """Source selection: uniform among the k nearest source demos by object pose."""
    yaw_symmetry: float | None = None
    """The object looks the same after this yaw turn [rad] (pi/2 for a cube): the current object frame is
    turned by a multiple of it to the one closest to the source's, so segments rotate as little as
    possible (and stay within the wrist's joint range)."""


@dataclass(frozen=True, kw_only=True)
class MimicCfg:
    """The subtask decomposition of a task for the controlled arm's TCP."""

    subtasks: tuple[SubtaskCfg, ...]
    arm: str = "left"
    select_src_per_subtask: bool = True
    interpolate_from_last_target_pose: bool = True
    rot_weight: float = 1.0
    """Weight of the rotation angle [rad] against position [m] in nearest-object selection."""
    settle_steps: int = 15
    """Steps the last target is held after the final segment before the attempt counts as done."""

    def __post_init__(self):
        if not self.subtasks or self.subtasks[-1].term_signal is not None:
            raise ValueError("the last Mimic subtask must have term_signal=None (it ends with the episode)")
        if self.subtasks[-1].term_offset_range != (0, 0):
            raise ValueError("the last Mimic subtask must have term_offset_range=(0, 0)")

    @property
    def signals(self) -> list[str]:
        return [s.term_signal for s in self.subtasks if s.term_signal]
