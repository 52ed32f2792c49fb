"""The pretraining losses: Temporal Cycle-Consistency, and REDS's EPIC Pearson distance and
supervised contrastive loss (runtime/reds.py describes REDS).

TCC is the deterministic regression-MSE form XIRL trains X-MAGICAL with. For every ordered
pair (u, v) of videos in a batch and every frame i of u: take the soft nearest neighbour of
u_i among v's frames, map it back onto u by a softmax over u's frames, and regress the
expected frame index of that return trip onto i (indices normalised to [0, 1] by the video's
length, so clips of different lengths weigh the same). Similarity is the negative squared
Euclidean distance divided by the embedding size and the temperature.
"""

from __future__ import annotations

import torch
from torch import nn


def pairwise_similarity(a: torch.Tensor, b: torch.Tensor, temperature: float) -> torch.Tensor:
    """(..., N, D), (..., M, D) -> (..., N, M) scaled negative squared distances."""
    return -torch.cdist(a, b).square() / (a.shape[-1] * temperature)


def tcc_loss(embeddings: torch.Tensor, frame_positions: torch.Tensor, temperature: float = 1.0) -> torch.Tensor:
    """Mean cycle-back regression error over all ordered pairs of distinct videos.

    embeddings: (B, T, D), frames of each video in temporal order.
    frame_positions: (B, T), each frame's position in its video, normalised to [0, 1].
    """
    if embeddings.ndim != 3 or embeddings.shape[0] < 2:
        raise ValueError(f"need embeddings shaped (videos >= 2, frames, dim), got {tuple(embeddings.shape)}")
    if frame_positions.shape != embeddings.shape[:2]:
        raise ValueError(f"frame_positions {tuple(frame_positions.shape)} must match {tuple(embeddings.shape[:2])}")
    videos = embeddings.shape[0]
    first, second = torch.meshgrid(*(torch.arange(videos, device=embeddings.device),) * 2, indexing="ij")
    keep = first != second
    u, v = embeddings[first[keep]], embeddings[second[keep]]  # (P, T, D) each
    alpha = torch.softmax(pairwise_similarity(u, v, temperature), dim=-1)  # u_i -> v
    nearest_in_v = alpha @ v  # (P, T, D)
    beta = torch.softmax(pairwise_similarity(nearest_in_v, u, temperature), dim=-1)  # back onto u
    positions = frame_positions[first[keep]].to(embeddings.dtype)  # (P, T)
    predicted = (beta * positions.unsqueeze(1)).sum(-1)
    return torch.mean((predicted - positions) ** 2)


def pearson_distance(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """EPIC's Pearson distance sqrt((1 - rho) / 2), in [0, 1]."""
    a, b = a - a.mean(), b - b.mean()
    rho = (a * b).mean() / (a.pow(2).mean().sqrt() * b.pow(2).mean().sqrt() + 1e-10)
    return torch.sqrt(0.5 * (1.0 - rho.clamp(max=1.0)) + 1e-12)


def supervised_contrastive_loss(features: torch.Tensor, labels: torch.Tensor, temperature: float) -> torch.Tensor:
    """SupCon (Khosla et al. 2020) over L2-normalised `features`: for each anchor, the mean
    log-probability of its same-label others among all its others; anchors alone in their label
    are left out."""
    features = nn.functional.normalize(features, dim=-1)
    logits = features @ features.T / temperature
    self_mask = torch.eye(len(features), dtype=torch.bool, device=features.device)
    logits = logits.masked_fill(self_mask, float("-inf"))
    log_probability = logits - torch.logsumexp(logits, dim=1, keepdim=True)
    positives = (labels[:, None] == labels[None, :]) & ~self_mask
    counts = positives.sum(dim=1)
    has = counts > 0
    mean_positive = torch.where(positives, log_probability, torch.zeros_like(log_probability)).sum(dim=1)
    return -(mean_positive[has] / counts[has]).mean()
