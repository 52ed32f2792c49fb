"""HOLD-R baseline (Alakuijala et al.): regress the number of steps from a frame to a later goal frame.

The published model is a ViViT video transformer. This is a deliberately small variant of
ViViT's factorised-encoder layout, sized for two CPU cores: a spatial transformer turns each
frame into one token, a temporal transformer reads the (frame, goal) token pair and predicts
the gap in steps. Its patch embedding is a small convolutional stem (ViT's "hybrid" input)
with batch norm rather than one strided linear projection. From scratch, frames of this
task differ in a few small regions, so plain projected patches barely differ between frames
and the regression sat at the predict-the-mean level (it could not even fit one batch).
Encoding the goal once and reusing its token keeps inference at one spatial forward per
frame, the same cost as the TCC encoders.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import torch
from torch import nn


@dataclass(frozen=True)
class HoldRConfig:
    patch_size: int = 16  # side of the square each token covers: the stem halves the image log2(patch_size) times
    width: int = 64
    heads: int = 4
    spatial_depth: int = 3
    temporal_depth: int = 1
    embedding_dim: int = 32
    steps_unit: float = 100.0  # targets are regressed in units of this many steps (the episode horizon)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def transformer(width: int, heads: int, depth: int) -> nn.TransformerEncoder:
    layer = nn.TransformerEncoderLayer(width, heads, 4 * width, dropout=0.0, batch_first=True, norm_first=True)
    return nn.TransformerEncoder(layer, depth, enable_nested_tensor=False)


class SpatialViT(nn.Module):
    """Patchify, add learned positions, transformer, class token -> frame embedding."""

    def __init__(self, config: HoldRConfig, image_size: int) -> None:
        super().__init__()
        if image_size % config.patch_size:
            raise ValueError(f"image_size {image_size} is not a multiple of patch_size {config.patch_size}")
        halvings = config.patch_size.bit_length() - 1
        if 2**halvings != config.patch_size:
            raise ValueError(f"patch_size must be a power of two, got {config.patch_size}")
        tokens = (image_size // config.patch_size) ** 2
        stem: list[nn.Module] = []
        channels = 3
        for step in range(halvings):
            out_channels = config.width if step == halvings - 1 else max(16, config.width >> (halvings - 1 - step))
            stem += [nn.Conv2d(channels, out_channels, 3, 2, 1, bias=False), nn.BatchNorm2d(out_channels), nn.GELU()]
            channels = out_channels
        self.patchify = nn.Sequential(*stem[:-1])
        self.class_token = nn.Parameter(torch.zeros(1, 1, config.width))
        self.positions = nn.Parameter(torch.randn(1, tokens + 1, config.width) * 0.02)
        self.blocks = transformer(config.width, config.heads, config.spatial_depth)
        self.norm = nn.LayerNorm(config.width)
        self.head = nn.Linear(config.width, config.embedding_dim)

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        patches = self.patchify(frames).flatten(2).transpose(1, 2)
        tokens = torch.cat([self.class_token.expand(len(patches), -1, -1), patches], dim=1) + self.positions
        return self.head(self.norm(self.blocks(tokens))[:, 0])


class HoldR(nn.Module):
    """d(s, g) in units of `steps_unit`: spatial tokens of s and g, temporal transformer, regression head."""

    def __init__(self, config: HoldRConfig, image_size: int) -> None:
        super().__init__()
        self.config = config
        self.spatial = SpatialViT(config, image_size)
        self.lift = nn.Linear(config.embedding_dim, config.width)
        self.class_token = nn.Parameter(torch.zeros(1, 1, config.width))
        self.time_positions = nn.Parameter(torch.randn(1, 3, config.width) * 0.02)
        self.temporal = transformer(config.width, config.heads, config.temporal_depth)
        self.norm = nn.LayerNorm(config.width)
        self.regress = nn.Linear(config.width, 1)

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        """The frame encoder, so HOLD-R embeds frames through the same interface as the TCC encoders."""
        return self.spatial(frames)

    def gap(self, frame_embeddings: torch.Tensor, goal_embeddings: torch.Tensor) -> torch.Tensor:
        pair = torch.stack([self.lift(frame_embeddings), self.lift(goal_embeddings)], dim=1)
        tokens = torch.cat([self.class_token.expand(len(pair), -1, -1), pair], dim=1) + self.time_positions
        return self.regress(self.norm(self.temporal(tokens))[:, 0]).squeeze(-1)
