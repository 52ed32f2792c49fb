"""REDS baseline without CLIP: "REDS (no CLIP)" (Kim et al., "Subtask-Aware Visual Reward Learning
from Segmented Demonstrations", ICLR 2025; thesis 5.2.4).

REDS learns a reward R(frames, z_k) conditioned on a subtask embedding z_k, from demonstrations
whose frames are labelled with the subtask being worked on. Training combines (thesis 5.2.4, the
paper, and its published learner):
- an EPIC loss: the Pearson distance sqrt((1 - rho) / 2) between the canonicalised learned and
  ground-truth rewards over a batch. The ground truth is the segmentation itself: a frame's
  reward is the number of subtasks completed on it (the paper's phase-to-reward table, 0..K).
  Canonicalisation, as the REDS code has it: each frame's reward minus the mean reward of
  `canonical_samples` frames drawn from random demonstrations, each conditioned on its own
  subtask (the transition terms of EPIC's canonicalisation dropped, as there);
- the progressive reward regulariser: a frame 1 to `next_max_gap - 1` steps later in the same
  demonstration, conditioned on its own subtask, must score at least `regulariser_margin` more
  (hinge, summed over the batch as in the REDS code);
- a supervised contrastive loss (SupCon, temperature 0.1) over the frames' features and the
  subtask embeddings together, labelled by subtask: features are pulled towards the embedding
  of the subtask they are in and away from the others.
At inference the subtask is the one whose embedding is most cosine-similar to the frame's
feature, with REDS's bias towards earlier subtasks (score (cos + 1) / 2 + eps (K - 1 - k),
eps = 0.05: "preventing unexpected phase changes"), and the reward is R(frame, z_k) of it.

What differs from REDS, and why:
- no CLIP: there is no pretrained CLIP (nor any model hub) here. The frame encoder is the
  project's small CNN trained from scratch (EncoderConfig), and the subtask embeddings are free
  learned vectors, one per subtask, in the encoder's feature space: REDS projects CLIP text
  embeddings of the subtask descriptions; with a learned projection of a fixed text embedding
  per subtask that is the same family of functions, minus the language prior.
- one frame, not a video window: REDS encodes a short causal window of frames (4 frames
  apart by a skip) with a transformer; the reward here sees one frame, as every reward of this
  project does (the scorer and the reward node score one frame per environment per step).
- the three losses are summed every iteration (weights 1); the REDS code draws one of EPIC and
  contrastive per iteration at random, the same in expectation.
- the reward head is a 2-hidden-layer MLP on [feature, z_k] (REDS: an MLP on the flattened
  window features and the text feature).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import torch
from inest_common.settings import check_choices
from torch import nn

from .encoders import EncoderConfig, build_encoder


@dataclass(frozen=True)
class RedsConfig:
    subtasks: Literal[1, 3, 6] = 3  # the segmentation REDS is trained on and conditions on (the thesis: one per block)
    hidden: int = 256  # reward head width
    frames_per_batch: int = 32  # anchor frames per pretraining batch
    canonical_samples: int = 8  # EPIC canonicalisation frames per anchor (REDS: pearson_size 8)
    next_max_gap: int = 20  # regulariser's later frame: 1 .. next_max_gap - 1 steps on (REDS: random_sample_end)
    epic_weight: float = 1.0
    regulariser_weight: float = 1.0  # REDS: lambda_epic_reg
    regulariser_margin: float = 0.05  # REDS: epic_eps
    contrastive_weight: float = 1.0
    temperature: float = 0.1  # REDS: supcon_temperature
    subtask_bias: float = 0.05  # inference: bias per subtask towards earlier ones (REDS: eps 5e-2)

    def __post_init__(self) -> None:
        check_choices(self, "reds.")
        for name in ("hidden", "frames_per_batch", "canonical_samples"):
            if getattr(self, name) < 1:
                raise ValueError(f"reds.{name} must be positive, got {getattr(self, name)}")
        if self.frames_per_batch < 2:
            raise ValueError("reds.frames_per_batch must be at least 2 (a correlation needs two frames)")
        if self.next_max_gap < 2:
            raise ValueError(f"reds.next_max_gap must be at least 2, got {self.next_max_gap}")
        if not self.temperature > 0 or self.subtask_bias < 0:
            raise ValueError("reds.temperature must be positive and reds.subtask_bias >= 0")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class Reds(nn.Module):
    """Frame encoder f(o), learned subtask embeddings z_k, reward head R(f, z) = MLP([f, z])."""

    def __init__(self, config: RedsConfig, encoder: EncoderConfig) -> None:
        super().__init__()
        self.config = config
        self.encoder = build_encoder(encoder)
        dim = encoder.embedding_dim
        self.subtask_embeddings = nn.Parameter(torch.randn(config.subtasks, dim) / dim**0.5)
        self.head = nn.Sequential(
            nn.Linear(2 * dim, config.hidden),
            nn.ReLU(),
            nn.Linear(config.hidden, config.hidden),
            nn.ReLU(),
            nn.Linear(config.hidden, 1),
        )

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        """The frame features, so REDS embeds frames through the same interface as the TCC encoders."""
        return self.encoder(frames)

    def reward(self, features: torch.Tensor, subtask_embeddings: torch.Tensor) -> torch.Tensor:
        """(N, D) features and (N, D) subtask embeddings -> (N,) rewards."""
        return self.head(torch.cat([features, subtask_embeddings], dim=-1)).squeeze(-1)


def subtask_scores(similarity: np.ndarray, bias: float) -> np.ndarray:
    """REDS's biased selection scores: (cos + 1) / 2 plus bias (K - 1 - k) for subtask k."""
    similarity = np.asarray(similarity, dtype=np.float64)
    count = similarity.shape[-1]
    return (similarity + 1.0) / 2.0 + bias * np.arange(count - 1, -1, -1)


def cosine_similarity(features: np.ndarray, subtask_embeddings: np.ndarray) -> np.ndarray:
    """(N, K) cosine similarity of every frame's feature to every subtask embedding."""
    features = np.asarray(features, dtype=np.float64)
    subtask_embeddings = np.asarray(subtask_embeddings, dtype=np.float64)
    norms = np.linalg.norm(features, axis=1, keepdims=True) * np.linalg.norm(subtask_embeddings, axis=1)[None]
    return features @ subtask_embeddings.T / np.maximum(norms, 1e-12)


def infer_subtasks(features: np.ndarray, subtask_embeddings: np.ndarray, bias: float) -> np.ndarray:
    """(N,) the subtask each frame is in, as REDS infers it online."""
    return np.argmax(subtask_scores(cosine_similarity(features, subtask_embeddings), bias), axis=1)
