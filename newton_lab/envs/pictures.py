"""Pictures of image observations for people: one row's frame of a camera as RGB | depth | segmentation panels."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import torch


def picture(images: Mapping[str, torch.Tensor], camera: str, row: int = 0) -> np.ndarray:
    """One row's frame of ``camera`` as an (H, k W, 3) uint8 picture: RGB | depth (near bright, far dark, nothing
    hit black) | segmentation (one colour per id), each panel the camera gives."""
    panels = []
    if f"{camera}_rgb" in images:
        panels.append(images[f"{camera}_rgb"][row].cpu().numpy())
    if f"{camera}_depth" in images:
        d = images[f"{camera}_depth"][row].cpu().numpy()
        hit = np.isfinite(d)
        lo, hi = (float(d[hit].min()), float(d[hit].max())) if hit.any() else (0.0, 1.0)
        g = np.where(hit, 1.0 - 0.85 * (d - lo) / max(hi - lo, 1e-6), 0.0)
        panels.append(np.repeat((255.0 * g).astype(np.uint8)[..., None], 3, axis=2))
    if f"{camera}_segmentation" in images:
        s = images[f"{camera}_segmentation"][row].cpu().numpy()
        palette = np.random.default_rng(7).integers(40, 256, size=(max(int(s.max()) + 1, 1), 3), dtype=np.uint8)
        palette[0] = 0
        panels.append(palette[s])
    if not panels:
        raise ValueError(f"no images of camera {camera!r}; the images are {list(images)}")
    return np.concatenate(panels, axis=1)
