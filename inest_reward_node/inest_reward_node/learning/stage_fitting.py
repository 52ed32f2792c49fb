"""Fitting the stage evidence at calibration: the stage classifier on embeddings
(runtime/stage_classifier.py) and the pixel stage head on frames (runtime/stage_head.py), on
frames labelled with their true stage, and the demonstrations' support of each stage
(runtime/stage_support.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
from inest_common.progress import track

from ..runtime.encoders import frames_to_tensor, resize_frames
from ..runtime.stage_classifier import StageClassifier
from ..runtime.stage_head import StageHead, StageHeadConfig
from ..runtime.stage_support import StageSupport

BOUNDARY_FRAMES = 2  # frames either side of a stage change that count as its boundary


@dataclass(frozen=True)
class StageClassifierConfig:
    """Fitting the stage classifier (full-batch Adam; about a second per subtask scheme)."""

    hidden: int = 64
    steps: int = 300
    learning_rate: float = 0.01
    weight_decay: float = 1e-4
    negative_weight: float = 1.0  # total weight of the non-demonstration frames, relative to the demos'
    max_demo_frames: int = 16384  # a uniform sample of the demonstrations' frames, if they have more
    seed: int = 0

    def __post_init__(self) -> None:
        if (
            min(self.hidden, self.steps, self.max_demo_frames) < 1
            or self.learning_rate <= 0
            or self.negative_weight < 0
        ):
            raise ValueError("hidden, steps and max_demo_frames must be >= 1, learning_rate > 0, negative_weight >= 0")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def fit_stage_classifier(
    demo_embeddings: Sequence[np.ndarray],
    demo_stages: Sequence[np.ndarray],
    num_stages: int,
    negative_embeddings: Sequence[np.ndarray] = (),
    negative_stages: Sequence[np.ndarray] = (),
    config: StageClassifierConfig | None = None,
) -> StageClassifier:
    """Fit P(stage | embedding) on demonstration frames and other behaviour (random play, wrong
    order), each frame labelled with its true stage. Every stage's demonstration frames weigh as
    much in total as any other's (a stage is as long as its subtask), and all non-demonstration
    frames together weigh `negative_weight` times the demonstrations."""
    config = config or StageClassifierConfig()
    x_demo, y_demo = np.concatenate(demo_embeddings), np.concatenate(demo_stages).astype(np.int64)
    if len(y_demo) > config.max_demo_frames:
        chosen = np.random.default_rng(config.seed).choice(len(y_demo), config.max_demo_frames, replace=False)
        x_demo, y_demo = x_demo[chosen], y_demo[chosen]
    counts = np.bincount(y_demo, minlength=num_stages).astype(np.float64)
    weights = [1.0 / counts[y_demo] / np.count_nonzero(counts)]
    xs, ys = [x_demo], [y_demo]
    if len(negative_embeddings) and config.negative_weight > 0:
        x_neg, y_neg = np.concatenate(negative_embeddings), np.concatenate(negative_stages).astype(np.int64)
        xs.append(x_neg)
        ys.append(y_neg)
        weights.append(np.full(len(y_neg), config.negative_weight / len(y_neg)))
    x, y, w = np.concatenate(xs).astype(np.float32), np.concatenate(ys), np.concatenate(weights)
    if y.min() < 0 or y.max() >= num_stages:
        raise ValueError(f"stage labels must lie in [0, {num_stages}), got {y.min()}..{y.max()}")
    mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-6
    generator = torch.Generator().manual_seed(config.seed)
    dim = x.shape[1]
    hidden_weight = (torch.randn(dim, config.hidden, generator=generator) * math.sqrt(2.0 / dim)).requires_grad_()
    hidden_bias = torch.zeros(config.hidden, requires_grad=True)
    out_weight = torch.randn(config.hidden, num_stages, generator=generator) / math.sqrt(config.hidden)
    out_weight.requires_grad_()
    out_bias = torch.zeros(num_stages, requires_grad=True)
    parameters = [hidden_weight, hidden_bias, out_weight, out_bias]
    optimizer = torch.optim.Adam(parameters, lr=config.learning_rate, weight_decay=config.weight_decay)
    inputs = torch.from_numpy((x - mean) / scale)
    targets = torch.from_numpy(y)
    frame_weights = torch.from_numpy((w / w.sum()).astype(np.float32))
    for _ in range(config.steps):
        logits = torch.relu(inputs @ hidden_weight + hidden_bias) @ out_weight + out_bias
        loss = (torch.nn.functional.cross_entropy(logits, targets, reduction="none") * frame_weights).sum()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    return StageClassifier(mean, scale, *(p.detach().numpy() for p in parameters))


def fit_stage_head(
    frames: list[np.ndarray],
    stages: list[np.ndarray],
    num_stages: int,
    config: StageHeadConfig,
    progress_bar: bool = False,
) -> StageHead:
    """Fit on episodes of frames (any size) with each frame's true stage; batches draw every stage
    equally often, so the rare later stages of random play count as much as the early ones.
    Minutes per subtask scheme at 96 px on one core, hence the optional progress bar."""
    head = StageHead(config, num_stages)
    images = np.concatenate([resize_frames(np.asarray(episode), config.image_size) for episode in frames])
    labels = np.concatenate(stages).astype(np.int64)
    by_stage = [np.flatnonzero(labels == stage) for stage in range(num_stages)]
    present = [members for members in by_stage if len(members)]
    near_change = boundary_frames(stages)
    rng = np.random.default_rng(config.seed)
    torch.manual_seed(config.seed)
    network = head.network.train()
    optimiser = torch.optim.Adam(network.parameters(), lr=config.learning_rate)
    from_boundary = round(config.batch_size * config.boundary_share) if len(near_change) else 0
    per_stage = max(1, (config.batch_size - from_boundary) // len(present))
    iterations = track(
        range(config.iterations), desc=f"stage head, {num_stages} stages", leave=False, disable=not progress_bar
    )
    for _ in iterations:
        index = np.concatenate(
            [rng.choice(members, per_stage) for members in present] + [rng.choice(near_change, from_boundary)]
        )
        logits = network(frames_to_tensor(images[index]))
        loss = torch.nn.functional.cross_entropy(logits, torch.as_tensor(labels[index]))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
    network.eval()
    return head


def fit_stage_support(
    demo_embeddings: Sequence[np.ndarray],
    demo_stages: Sequence[np.ndarray],
    num_stages: int,
    quantile: float,
    references: int,
    held_out_every: int = 5,
    seed: int = 0,
) -> StageSupport:
    """Per stage j >= 1: a radius covering `quantile` of the stage-j frames of every
    `held_out_every`-th demonstration, measured to the nearest of up to `references` stage-j frames
    of the other demonstrations (so that a new frame like a demonstration's falls inside); then up
    to `references` stage-j frames of all the demonstrations, held-out ones included, are kept as
    the references (a little more than `quantile` of new demonstration frames fall inside)."""
    rng = np.random.default_rng(seed)
    held_out = np.arange(len(demo_embeddings)) % held_out_every == 0
    kept, radii = [], []
    for stage in range(1, num_stages):
        frames = [emb[stages == stage] for emb, stages in zip(demo_embeddings, demo_stages, strict=True)]
        fitted = np.concatenate([f for f, out in zip(frames, held_out, strict=True) if not out] or [np.zeros((0, 1))])
        checked = np.concatenate([f for f, out in zip(frames, held_out, strict=True) if out] or [np.zeros((0, 1))])
        if not len(fitted) or not len(checked):
            raise ValueError(f"stage {stage} has too few demonstration frames to fit its support")
        fitted = fitted[rng.permutation(len(fitted))[:references]]
        distances = StageSupport([fitted], [np.inf], quantile).distances(checked)[:, 1]
        radii.append(float(np.quantile(distances, quantile)))
        everything = np.concatenate(frames)
        kept.append(everything[rng.permutation(len(everything))[:references]])
    return StageSupport(kept, radii, quantile)


def boundary_frames(stages: list[np.ndarray]) -> np.ndarray:
    """Indices into the concatenated episodes of the frames within BOUNDARY_FRAMES of a change of
    stage inside their episode (both sides of it)."""
    near: list[np.ndarray] = []
    offset = 0
    for episode in stages:
        changes = np.flatnonzero(np.diff(episode) != 0) + 1  # the first frame of each new stage
        for change in changes:
            start, stop = max(0, change - BOUNDARY_FRAMES), min(len(episode), change + BOUNDARY_FRAMES)
            near.append(offset + np.arange(start, stop))
        offset += len(episode)
    return np.unique(np.concatenate(near)) if near else np.zeros(0, np.int64)
