"""Image encoder of the visuomotor diffusion policy (Chi et al. 2023): per camera a ResNet-18-style trunk with
GroupNorm instead of BatchNorm (batch statistics fight the EMA and small batches) and a spatial-softmax head
(expected image coordinates of learned keypoints), then a linear layer to the feature size. Written here because
there is no CPU torchvision for this torch; the trunk follows torchvision's resnet18 layout (stem, 4 stages of 2
basic blocks) with a configurable base width.

Frames arrive as uint8 (B, T, H, W, 3); training crops each frame at a random position (``crop`` of each side),
evaluation at the centre.

An instruction (a task's per-row target, e.g. which object to pick) can condition the trunks too: each residual
block's output is scaled and shifted per channel by a linear map of it (FiLM, Perez et al. 2018; RT-1 conditions its
image trunk on the instruction this way), so the keypoints can follow the object the instruction names rather than
every object the scene holds. The maps start at zero: a fresh conditioned trunk computes what an unconditioned one
does.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import torch
import torch.nn.functional as F
from torch import nn

from .data_parallel import draw_rows
from .norm import GroupNorm


def _norm(channels: int) -> GroupNorm:
    return GroupNorm(max(1, channels // 16), channels)  # 16 channels per group, as Chi et al. replace BN


class BasicBlock(nn.Module):
    """Two 3x3 conv + GroupNorm layers with a residual (1x1 conv when the stride or width changes); with
    ``instruction_dim`` > 0 the second norm's output is FiLM-modulated by the instruction, ``h * (1 + scale) +
    shift`` per channel (zero-initialised)."""

    def __init__(self, c_in: int, c_out: int, stride: int = 1, instruction_dim: int = 0) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(c_in, c_out, 3, stride, 1, bias=False)
        self.norm1 = _norm(c_out)
        self.conv2 = nn.Conv2d(c_out, c_out, 3, 1, 1, bias=False)
        self.norm2 = _norm(c_out)
        self.shortcut = (
            nn.Identity()
            if stride == 1 and c_in == c_out
            else nn.Sequential(nn.Conv2d(c_in, c_out, 1, stride, bias=False), _norm(c_out))
        )
        self.film = nn.Linear(instruction_dim, 2 * c_out) if instruction_dim > 0 else None
        if self.film is not None:
            nn.init.zeros_(self.film.weight)
            nn.init.zeros_(self.film.bias)

    def forward(self, x: torch.Tensor, instruction: torch.Tensor | None = None) -> torch.Tensor:
        h = F.relu(self.norm1(self.conv1(x)))
        h = self.norm2(self.conv2(h))
        if self.film is not None:
            scale, shift = self.film(instruction)[:, :, None, None].chunk(2, dim=1)
            h = h * (1.0 + scale) + shift
        return F.relu(h + self.shortcut(x))


class ResNetGN(nn.Module):
    """ResNet-18 trunk (no pooling head): 7x7/2 stem, 3x3/2 max-pool, stages of widths w, 2w, 4w, 8w; every block
    FiLM-conditioned on an ``instruction_dim`` vector when that is > 0."""

    def __init__(self, width: int = 64, in_channels: int = 3, instruction_dim: int = 0) -> None:
        super().__init__()
        self.stem = nn.Sequential(
            nn.Conv2d(in_channels, width, 7, 2, 3, bias=False), _norm(width), nn.ReLU(), nn.MaxPool2d(3, 2, 1)
        )
        widths, layers, c = (width, 2 * width, 4 * width, 8 * width), [], width
        for i, w in enumerate(widths):
            stride = 1 if i == 0 else 2
            layers += [BasicBlock(c, w, stride, instruction_dim), BasicBlock(w, w, 1, instruction_dim)]
            c = w
        self.stages = nn.Sequential(*layers)
        self.out_channels = c

    def forward(self, x: torch.Tensor, instruction: torch.Tensor | None = None) -> torch.Tensor:
        h = self.stem(x)
        for block in self.stages:
            h = block(h, instruction)
        return h


class SpatialSoftmax(nn.Module):
    """(N, C, H, W) features -> (N, 2K): the expected (x, y) in [-1, 1] of K keypoint heat maps (1x1 conv)."""

    def __init__(self, channels: int, keypoints: int = 32) -> None:
        super().__init__()
        self.keypoints = nn.Conv2d(channels, keypoints, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        heat = self.keypoints(x)
        n, k, h, w = heat.shape
        attention = torch.softmax(heat.flatten(2), dim=-1)  # (N, K, H*W)
        ys = torch.linspace(-1.0, 1.0, h, device=x.device, dtype=attention.dtype)
        xs = torch.linspace(-1.0, 1.0, w, device=x.device, dtype=attention.dtype)
        grid = torch.stack(torch.meshgrid(xs, ys, indexing="xy"), dim=-1).reshape(h * w, 2)  # (H*W, 2): (x, y)
        return (attention @ grid).reshape(n, 2 * k)


def crop_frames(x: torch.Tensor, size: tuple[int, int], random: bool) -> torch.Tensor:
    """(N, H, W, C) -> (N, h, w, C): per-frame random windows (``random``) or the centre window."""
    n, height, width = x.shape[:3]
    h, w = size
    if random:
        oy = draw_rows(lambda k: torch.randint(0, height - h + 1, (k,), device=x.device), n)
        ox = draw_rows(lambda k: torch.randint(0, width - w + 1, (k,), device=x.device), n)
    else:
        oy = torch.full((n,), (height - h) // 2, device=x.device)
        ox = torch.full((n,), (width - w) // 2, device=x.device)
    rows = oy[:, None] + torch.arange(h, device=x.device)
    cols = ox[:, None] + torch.arange(w, device=x.device)
    return x[torch.arange(n, device=x.device)[:, None, None], rows[:, :, None], cols[:, None, :]]


class CameraEncoder(nn.Module):
    """One camera: trunk (instruction-conditioned with ``instruction_dim`` > 0) -> spatial softmax -> linear ->
    ``feature_dim`` features."""

    def __init__(self, width: int, feature_dim: int, keypoints: int = 32, instruction_dim: int = 0) -> None:
        super().__init__()
        self.trunk = ResNetGN(width, instruction_dim=instruction_dim)
        self.pool = SpatialSoftmax(self.trunk.out_channels, keypoints)
        self.out = nn.Linear(2 * keypoints, feature_dim)

    def forward(self, x: torch.Tensor, instruction: torch.Tensor | None = None) -> torch.Tensor:
        return self.out(self.pool(self.trunk(x, instruction)))


def crop_size(shape: Sequence[int], crop: float) -> tuple[int, int]:
    """The (h, w) window a ``crop`` fraction of an (H, W, ...) frame keeps [px]."""
    return max(1, round(shape[0] * crop)), max(1, round(shape[1] * crop))


class ImageEncoder(nn.Module):
    """Every image key's frames -> concatenated features: (B, T, H, W, C) uint8 per key -> (B, T, n * feature_dim);
    with ``instruction_dim`` > 0 every trunk is conditioned on a (B, T, instruction_dim) instruction."""

    def __init__(
        self,
        shapes: Mapping[str, Sequence[int]],
        *,
        crop: float = 0.9,
        feature_dim: int = 64,
        width: int = 64,
        instruction_dim: int = 0,
    ) -> None:
        super().__init__()
        self.keys = list(shapes)
        self.shapes = {k: tuple(int(v) for v in s) for k, s in shapes.items()}
        self.crops = {k: crop_size(s, crop) for k, s in self.shapes.items()}
        self.instruction_dim = int(instruction_dim)
        self.cameras = nn.ModuleDict(
            {k: CameraEncoder(width, feature_dim, instruction_dim=self.instruction_dim) for k in self.keys}
        )
        self.feature_dim = feature_dim * len(self.keys)

    def check(self, images: Mapping[str, torch.Tensor]) -> None:
        """One-line error for missing keys or frames of another size."""
        missing = [k for k in self.keys if k not in images]
        if missing:
            raise ValueError(f"images {missing} are missing; the policy sees {self.keys}")
        for k in self.keys:
            if tuple(images[k].shape[2:]) != self.shapes[k]:
                raise ValueError(
                    f"image {k} frames are {tuple(images[k].shape[2:])}, the policy was trained on "
                    f"{self.shapes[k]} (H, W, C); render the env's camera at that size"
                )

    def forward(self, images: Mapping[str, torch.Tensor], instruction: torch.Tensor | None = None) -> torch.Tensor:
        feats = []
        device = next(self.parameters()).device
        if self.instruction_dim and instruction is None:
            raise ValueError(f"this image encoder is conditioned on a {self.instruction_dim}-wide instruction; pass it")
        for k in self.keys:
            x = images[k].to(device)
            b, t = x.shape[:2]
            x = crop_frames(x.reshape(b * t, *x.shape[2:]), self.crops[k], random=self.training)
            x = x.permute(0, 3, 1, 2).float().div_(127.5).sub_(1.0)  # uint8 -> [-1, 1]
            per_frame = None if not self.instruction_dim else instruction.to(device).reshape(b * t, -1)
            feats.append(self.cameras[k](x, per_frame).reshape(b, t, -1))
        return torch.cat(feats, dim=-1)
