"""Mimic: MimicGen-style dataset expansion over recorded subtask signals (object-centric transforms of
source segments, stitched by interpolation, executed on a batched env through batched IK)."""

from .config import MimicCfg, SubtaskCfg
from .generate import mimic, mimic_variant_of

__all__ = ["MimicCfg", "SubtaskCfg", "mimic", "mimic_variant_of"]
