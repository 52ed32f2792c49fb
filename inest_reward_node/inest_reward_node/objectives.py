"""Pretraining objectives, one class per representation method (XIRL's trainer-per-loss layout).

`TCCObjective` trains a frame encoder with Temporal Cycle-Consistency (INEST-IRL and XIRL);
`HoldRObjective` regresses the step gap between a frame and a later goal frame (HOLD-R).
`OBJECTIVES` maps a `--method` name to its class; the Pretrainer (pretrain.py) only calls `loss`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

import numpy as np
import torch

from .data import Demo, augment_videos, sample_goal_pairs, sample_tcc_batch
from .encoders import frames_to_tensor
from .tcc import tcc_loss

if TYPE_CHECKING:
    from .pretrain import PretrainConfig


class Objective:
    """A pretraining loss over batches drawn from demonstrations."""

    # PretrainConfig fields this method never reads (a resumed run may change them freely)
    unused_settings: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, config: PretrainConfig, network: torch.nn.Module) -> None:
        self.config = config
        self.network = network

    @classmethod
    def check_config(cls, config: PretrainConfig) -> None:
        """Raise ValueError for settings this method cannot train with."""

    def embed_clips(self, clips: np.ndarray, generator: torch.Generator) -> torch.Tensor:
        """uint8 (B, T, S, S, 3) -> augmented (B, T, D) embeddings."""
        videos, frames, size = clips.shape[0], clips.shape[1], clips.shape[2]
        images = frames_to_tensor(clips.reshape(-1, size, size, 3), channels_last=False)
        images = augment_videos(images.view(videos, frames, 3, size, size), self.config.augment, generator)
        images = images.flatten(0, 1)
        if self.config.encoder.channels_last:
            images = images.contiguous(memory_format=torch.channels_last)
        return self.network(images).view(videos, frames, -1)

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        raise NotImplementedError


class TCCObjective(Objective):
    """TCC over `videos_per_batch` clips of `frames_per_video` frames, all ordered pairs of them."""

    unused_settings = frozenset({"holdr", "pairs_per_batch"})

    @classmethod
    def check_config(cls, config: PretrainConfig) -> None:
        if config.videos_per_batch < 2:
            raise ValueError("TCC needs at least 2 videos per batch")

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        config = self.config
        clips, positions = sample_tcc_batch(demos, config.videos_per_batch, config.frames_per_video, rng)
        embeddings = self.embed_clips(clips, generator)
        return tcc_loss(embeddings, torch.from_numpy(positions), config.temperature)


class HoldRObjective(Objective):
    """MSE between HOLD-R's predicted and the true step gap of `pairs_per_batch` (frame, goal) pairs,
    in units of `holdr.steps_unit`."""

    unused_settings = frozenset({"videos_per_batch", "frames_per_video", "temperature"})

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        config = self.config
        starts, goals, gaps = sample_goal_pairs(demos, config.pairs_per_batch, rng)
        embeddings = self.embed_clips(np.stack([starts, goals], axis=1), generator)
        predicted = self.network.gap(embeddings[:, 0], embeddings[:, 1])
        return torch.nn.functional.mse_loss(predicted, torch.from_numpy(gaps) / config.holdr.steps_unit)


OBJECTIVES: dict[str, type[Objective]] = {"tcc": TCCObjective, "holdr": HoldRObjective}
