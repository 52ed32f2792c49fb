"""Pretraining objectives, one class per representation method (XIRL's trainer-per-loss layout).

`TCCObjective` trains a frame encoder with Temporal Cycle-Consistency (INEST-IRL and XIRL);
`HoldRObjective` regresses the step gap between a frame and a later goal frame (HOLD-R);
`RedsObjective` trains REDS's subtask-conditioned reward (EPIC, progressive regulariser, contrastive).
`OBJECTIVES` maps a `--method` name to its class; the Pretrainer (pretrain.py) only calls `loss`.
"""

from __future__ import annotations

import numpy as np
import torch

from ..runtime.encoders import frames_to_tensor
from .config import PretrainConfig
from .data import Demo, augment_videos, sample_goal_pairs, sample_reds_batch, sample_tcc_batch
from .losses import pearson_distance, supervised_contrastive_loss, tcc_loss


class Objective:
    """A pretraining loss over batches drawn from demonstrations."""

    def __init__(self, config: PretrainConfig, network: torch.nn.Module) -> None:
        self.config = config
        self.network = network

    def tensor(self, array: np.ndarray) -> torch.Tensor:
        """A batch array as a tensor on the network's device."""
        return torch.from_numpy(array).to(self.config.device)

    def embed_clips(self, clips: np.ndarray, generator: torch.Generator) -> torch.Tensor:
        """uint8 (B, T, S, S, 3) -> augmented (B, T, D) embeddings."""
        videos, frames, size = clips.shape[0], clips.shape[1], clips.shape[2]
        images = frames_to_tensor(clips.reshape(-1, size, size, 3), channels_last=False)
        images = augment_videos(images.view(videos, frames, 3, size, size), self.config.augment, generator)
        images = images.flatten(0, 1).to(self.config.device)
        if self.config.encoder.channels_last:
            images = images.contiguous(memory_format=torch.channels_last)
        return self.network(images).view(videos, frames, -1)

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        raise NotImplementedError


class TCCObjective(Objective):
    """TCC over `videos_per_batch` clips of `frames_per_video` frames, all ordered pairs of them."""

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        config = self.config
        clips, positions = sample_tcc_batch(demos, config.videos_per_batch, config.frames_per_video, rng)
        embeddings = self.embed_clips(clips, generator)
        return tcc_loss(embeddings, self.tensor(positions), config.temperature)


class HoldRObjective(Objective):
    """MSE between HOLD-R's predicted and the true step gap of `pairs_per_batch` (frame, goal) pairs,
    in units of `holdr.steps_unit`."""

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        config = self.config
        starts, goals, gaps = sample_goal_pairs(demos, config.pairs_per_batch, rng)
        embeddings = self.embed_clips(np.stack([starts, goals], axis=1), generator)
        predicted = self.network.gap(embeddings[:, 0], embeddings[:, 1])
        return torch.nn.functional.mse_loss(predicted, self.tensor(gaps) / config.holdr.steps_unit)


class RedsObjective(Objective):
    """REDS (no CLIP, runtime/reds.py): per batch of `reds.frames_per_batch` anchor frames,
    epic_weight x (EPIC Pearson distance + regulariser_weight x progressive hinge)
    + contrastive_weight x SupCon of the frames' features and their subtasks' embeddings.
    Every frame is augmented on its own (a one-frame clip)."""

    def embed_frames(self, frames: np.ndarray, generator: torch.Generator) -> torch.Tensor:
        """uint8 (N, S, S, 3) -> augmented (N, D) features."""
        return self.embed_clips(frames[:, None], generator)[:, 0]

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        reds = self.config.reds
        batch = sample_reds_batch(
            demos, reds.subtasks, reds.frames_per_batch, reds.canonical_samples, reds.next_max_gap, rng
        )
        count, canonical = batch.canonical_labels.shape
        others = batch.canonical_frames.reshape(-1, *batch.frames.shape[1:])
        features = self.embed_frames(np.concatenate([batch.frames, batch.next_frames, others]), generator)
        anchor, later, others = features[:count], features[count : 2 * count], features[2 * count :]
        subtasks = self.network.subtask_embeddings
        labels = self.tensor(batch.labels)
        reward = self.network.reward(anchor, subtasks[labels])
        canonical_reward = self.network.reward(others, subtasks[self.tensor(batch.canonical_labels.reshape(-1))])
        learned = reward - canonical_reward.view(count, canonical).mean(dim=1)
        truth = self.tensor(batch.targets - batch.canonical_targets.mean(axis=1))
        epic = pearson_distance(learned, truth)
        later_reward = self.network.reward(later, subtasks[self.tensor(batch.next_labels)])
        regulariser = torch.relu(reds.regulariser_margin - later_reward + reward).sum()
        contrastive = supervised_contrastive_loss(
            torch.cat([anchor, subtasks[labels]]), torch.cat([labels, labels]), reds.temperature
        )
        return reds.epic_weight * (epic + reds.regulariser_weight * regulariser) + reds.contrastive_weight * contrastive


OBJECTIVES: dict[str, type[Objective]] = {"tcc": TCCObjective, "holdr": HoldRObjective, "reds": RedsObjective}
