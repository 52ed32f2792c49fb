"""Frame encoders: a plain-torch ResNet-18 (the thesis's backbone) and a small CNN (the fast one).

Both map uint8 RGB frames to a low-dimensional embedding whose Euclidean distances the
reward is built on. Weights start random: no pretrained ImageNet weights can be fetched
here, a documented deviation from the thesis (which fine-tunes an ImageNet ResNet-18).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import torch
from inest_common.settings import check_choices
from torch import nn

from .images import fit_square

ENCODER_KINDS = ("small_cnn", "resnet18")


@dataclass(frozen=True)
class EncoderConfig:
    kind: Literal[ENCODER_KINDS] = "small_cnn"  # the frame encoder's network
    embedding_dim: int = 32
    image_size: int = 96  # frames of any other size are resized to this before encoding
    channels_last: bool = True
    widths: tuple[int, ...] = (32, 64, 64, 64)  # small_cnn: output channels of its strided convolutions

    def __post_init__(self) -> None:
        object.__setattr__(self, "widths", tuple(self.widths))  # JSON gives a list
        check_choices(self, "encoder ")
        if not self.widths or min(self.widths) < 1:
            raise ValueError(f"widths must be positive channel counts, got {list(self.widths)}")
        if self.embedding_dim <= 0:
            raise ValueError(f"embedding_dim must be positive, got {self.embedding_dim}")
        if self.image_size < 32:
            raise ValueError(f"image_size must be at least 32 px, got {self.image_size}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class BasicBlock(nn.Module):
    """ResNet's two-conv residual block with an optional strided projection shortcut."""

    def __init__(self, in_channels: int, out_channels: int, stride: int) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(out_channels)
        self.conv2 = nn.Conv2d(out_channels, out_channels, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(out_channels)
        self.shortcut: nn.Module = nn.Identity()
        if stride != 1 or in_channels != out_channels:
            self.shortcut = nn.Sequential(
                nn.Conv2d(in_channels, out_channels, 1, stride, bias=False), nn.BatchNorm2d(out_channels)
            )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out = torch.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return torch.relu(out + self.shortcut(x))


class ResNet18(nn.Module):
    """torchvision's ResNet-18 layout (7x7 stem, four stages of two blocks, 512-d pool) + linear head."""

    feature_dim = 512

    def __init__(self, embedding_dim: int) -> None:
        super().__init__()
        self.stem = nn.Sequential(
            nn.Conv2d(3, 64, 7, 2, 3, bias=False),
            nn.BatchNorm2d(64),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(3, 2, 1),
        )
        stages, in_channels = [], 64
        for out_channels, stride in ((64, 1), (128, 2), (256, 2), (512, 2)):
            stages += [BasicBlock(in_channels, out_channels, stride), BasicBlock(out_channels, out_channels, 1)]
            in_channels = out_channels
        self.stages = nn.Sequential(*stages)
        self.pool = nn.AdaptiveAvgPool2d(1)
        self.head = nn.Sequential(nn.BatchNorm1d(self.feature_dim), nn.Linear(self.feature_dim, embedding_dim))
        for module in self.modules():
            if isinstance(module, nn.Conv2d):
                nn.init.kaiming_normal_(module.weight, mode="fan_out", nonlinearity="relu")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(torch.flatten(self.pool(self.stages(self.stem(x))), 1))


class SmallCNN(nn.Module):
    """Four strided 3x3 convolutions, then an MLP over the flattened map.

    Flattening instead of global pooling keeps where things are, which is what this task's
    progress is about (blocks relative to the goal strip and the gripper). Batch norm matters
    when training from scratch: without it, random features of frames that differ in a few
    pixels lie so close that TCC's softmaxes start uniform and the loss sits on a plateau.
    """

    def __init__(self, embedding_dim: int, image_size: int, widths: tuple[int, ...]) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        in_channels = 3
        for out_channels in widths:
            layers += [nn.Conv2d(in_channels, out_channels, 3, 2, 1, bias=False), nn.BatchNorm2d(out_channels)]
            layers.append(nn.ReLU(inplace=True))
            in_channels = out_channels
        self.features = nn.Sequential(*layers)
        side = image_size
        for _ in widths:
            side = (side + 1) // 2
        self.head = nn.Sequential(
            nn.Flatten(),
            nn.Linear(in_channels * side * side, 256, bias=False),
            nn.BatchNorm1d(256),
            nn.ReLU(inplace=True),
            nn.Linear(256, embedding_dim),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x))


def build_encoder(config: EncoderConfig) -> nn.Module:
    model = (
        ResNet18(config.embedding_dim)
        if config.kind == "resnet18"
        else SmallCNN(config.embedding_dim, config.image_size, config.widths)
    )
    if config.channels_last:
        model = model.to(memory_format=torch.channels_last)
    return model


def resize_frames(frames: np.ndarray, size: int, resize: str = "crop") -> np.ndarray:
    """(N, H, W, 3) uint8 -> (N, size, size, 3) by `images.fit_square`: non-square frames are
    centre-cropped to the training camera's square (`resize="squash"` keeps all of them)."""
    if frames.ndim != 4 or frames.shape[-1] != 3:
        raise ValueError(f"expected frames shaped (N, H, W, 3), got {frames.shape}")
    if frames.shape[1:3] == (size, size):
        return frames
    return np.stack([fit_square(frame, size, resize) for frame in frames])


def frames_to_tensor(frames: np.ndarray | torch.Tensor, channels_last: bool = True) -> torch.Tensor:
    """uint8 (N, H, W, 3) -> float (N, 3, H, W) in [-1, 1], in the memory layout the encoder wants."""
    tensor = torch.as_tensor(frames)
    if tensor.dtype != torch.uint8:
        raise ValueError(f"expected uint8 frames, got {tensor.dtype}")
    tensor = tensor.permute(0, 3, 1, 2).float().mul_(2.0 / 255.0).sub_(1.0)
    return tensor.contiguous(memory_format=torch.channels_last if channels_last else torch.contiguous_format)
