"""Mimic: MimicGen-style dataset expansion over recorded subtask signals (object-centric transforms of
source segments, stitched by interpolation, executed on a batched env through batched IK)."""

from ..task_api.mimic_cfg import MimicCfg, SubtaskCfg
from ..task_api.registry import mimic_variant_of
from .agent import MimicAgent
from .generate import mimic

__all__ = ["MimicAgent", "MimicCfg", "SubtaskCfg", "mimic", "mimic_variant_of"]
