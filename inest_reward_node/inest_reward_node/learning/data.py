"""Demonstration frames in memory, batch samplers for the pretraining objectives, augmentation."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from inest_common.progress import track
from inest_sim_node.dataset import DatasetError, DemoDataset, Episode

from ..runtime.encoders import resize_frames
from .task_stages import demo_stages


@dataclass
class Demo:
    """What representation learning and reward evaluation need from one episode."""

    seed: int
    frames: np.ndarray  # (T+1, S, S, 3) uint8 at the encoder's input size
    rewards: np.ndarray | None  # (T,) the environment's dense reward; None for a robot's recordings
    progress: np.ndarray  # (T+1,) ordered blocks in the goal
    labels: dict[int, np.ndarray]
    ends: dict[int, np.ndarray]

    def __len__(self) -> int:
        return len(self.frames)

    @classmethod
    def from_episode(cls, episode: Episode, view: str, image_size: int) -> Demo:
        if episode.progress is None:
            raise DatasetError("the demonstrations have no subtask ends: label them with inest-label-demos")
        return cls(
            seed=episode.seed,
            frames=resize_frames(episode.frames(view), image_size),
            rewards=episode.rewards,
            progress=episode.progress,
            labels=episode.labels,
            ends=episode.ends,
        )


def load_demos(
    root: str | Path, split: str, view: str, image_size: int, limit: int | None = None, progress_bar: bool = True
) -> list[Demo]:
    dataset = DemoDataset(root)
    count = len(dataset.entries(split))
    count = count if limit is None else min(limit, count)
    indices = track(range(count), desc=f"loading {split}", unit="demo", disable=not progress_bar, leave=False)
    return [Demo.from_episode(dataset.load(split, index), view, image_size) for index in indices]


def stratified_indices(length: int, count: int, rng: np.random.Generator) -> np.ndarray:
    """`count` sorted frame indices, one drawn uniformly from each of `count` equal stretches."""
    edges = np.linspace(0, length, count + 1)
    return np.minimum(np.floor(edges[:-1] + rng.random(count) * np.diff(edges)).astype(np.int64), length - 1)


def sample_tcc_batch(
    demos: list[Demo], videos: int, frames_per_video: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """(videos, frames, S, S, 3) uint8 clips in temporal order and their positions in [0, 1]."""
    chosen = rng.choice(len(demos), size=videos, replace=len(demos) < videos)
    clips, positions = [], []
    for index in chosen:
        demo = demos[index]
        frame_indices = stratified_indices(len(demo), frames_per_video, rng)
        clips.append(demo.frames[frame_indices])
        positions.append(frame_indices / max(len(demo) - 1, 1))
    return np.stack(clips), np.stack(positions).astype(np.float32)


def sample_goal_pairs(
    demos: list[Demo], pairs: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """HOLD-R training pairs: a frame, a uniformly drawn later (or same) frame of the same demo, their gap."""
    chosen = rng.integers(len(demos), size=pairs)
    starts, goals, gaps = [], [], []
    for index in chosen:
        demo = demos[index]
        goal = int(rng.integers(len(demo)))
        start = int(rng.integers(goal + 1))
        starts.append(demo.frames[start])
        goals.append(demo.frames[goal])
        gaps.append(goal - start)
    return np.stack(starts), np.stack(goals), np.asarray(gaps, dtype=np.float32)


@dataclass
class RedsBatch:
    """REDS training frames: anchors, each one's later frame (the progressive regulariser) and its
    EPIC canonicalisation frames; per frame the subtask label it is conditioned on (0..K-1) and its
    ground-truth segmentation reward (subtasks completed on it, 0..K)."""

    frames: np.ndarray  # (B, S, S, 3) uint8
    labels: np.ndarray  # (B,) int64
    targets: np.ndarray  # (B,) float32
    next_frames: np.ndarray  # (B, S, S, 3)
    next_labels: np.ndarray  # (B,)
    canonical_frames: np.ndarray  # (B, C, S, S, 3), C canonicalisation frames per anchor
    canonical_labels: np.ndarray  # (B, C)
    canonical_targets: np.ndarray  # (B, C)


def segmentation(demo: Demo, scheme: int) -> tuple[np.ndarray, np.ndarray]:
    """Per frame: the subtask label (what REDS conditions on) and the subtasks completed (its reward)."""
    labels = np.asarray(demo.labels[scheme], dtype=np.int64)
    return labels, demo_stages(demo.progress, labels, scheme).astype(np.float32)


def sample_reds_batch(
    demos: list[Demo], scheme: int, frames: int, canonical: int, next_max_gap: int, rng: np.random.Generator
) -> RedsBatch:
    """Anchors uniform over demonstrations and their frames; the later frame 1 .. next_max_gap - 1
    steps on (clipped to the last frame); the canonicalisation frames uniform over all demonstrations."""
    segments = [segmentation(demo, scheme) for demo in demos]

    def draw(count: int) -> tuple[np.ndarray, np.ndarray]:
        chosen = rng.integers(len(demos), size=count)
        return chosen, np.array([int(rng.integers(len(demos[d]))) for d in chosen], dtype=np.int64)

    anchors, times = draw(frames)
    later = np.minimum(times + rng.integers(1, next_max_gap, size=frames), [len(demos[d]) - 1 for d in anchors])
    others, other_times = draw(frames * canonical)

    def gather(chosen: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        images = np.stack([demos[d].frames[t] for d, t in zip(chosen, at, strict=True)])
        labels = np.array([segments[d][0][t] for d, t in zip(chosen, at, strict=True)], dtype=np.int64)
        targets = np.array([segments[d][1][t] for d, t in zip(chosen, at, strict=True)], dtype=np.float32)
        return images, labels, targets

    images, labels, targets = gather(anchors, times)
    next_images, next_labels, _ = gather(anchors, later)
    canonical_images, canonical_labels, canonical_targets = gather(others, other_times)
    return RedsBatch(
        images,
        labels,
        targets,
        next_images,
        next_labels,
        canonical_images.reshape(frames, canonical, *canonical_images.shape[1:]),
        canonical_labels.reshape(frames, canonical),
        canonical_targets.reshape(frames, canonical),
    )


@dataclass(frozen=True)
class AugmentConfig:
    """Per-video random shift, brightness and contrast.

    Block colour is the task signal (red, then blue, then yellow), so there is deliberately no
    hue jitter, channel shuffle or greyscale: brightness scales all three channels alike and
    contrast blends toward the frame's grey level, both of which keep every pixel's hue.
    """

    enabled: bool = True
    max_shift: int = 4  # pixels, replicate-padded
    brightness: float = 0.2  # factor drawn from [1 - b, 1 + b]
    contrast: float = 0.2

    def __post_init__(self) -> None:
        if self.max_shift < 0:
            raise ValueError(f"augment max_shift must be >= 0 pixels, got {self.max_shift}")
        for name in ("brightness", "contrast"):
            if not 0.0 <= getattr(self, name) < 1.0:  # a factor of 1 - b must stay positive
                raise ValueError(f"augment {name} must be in [0, 1), got {getattr(self, name)}")


def augment_videos(clips: torch.Tensor, config: AugmentConfig, generator: torch.Generator) -> torch.Tensor:
    """clips: float (B, T, 3, S, S) in [-1, 1]; one draw of every parameter per video, so
    augmentation never looks like motion inside a clip."""
    if not config.enabled:
        return clips
    videos, frames, channels, height, width = clips.shape
    pad = config.max_shift
    padded = torch.nn.functional.pad(clips.reshape(videos, frames * channels, height, width), (pad,) * 4, "replicate")
    shifts = torch.randint(0, 2 * pad + 1, (videos, 2), generator=generator)
    shifted = torch.stack(
        [padded[i, :, dy : dy + height, dx : dx + width] for i, (dy, dx) in enumerate(shifts.tolist())]
    ).reshape(clips.shape)

    def factor(spread: float) -> torch.Tensor:
        return (1.0 + (torch.rand(videos, generator=generator) * 2 - 1) * spread).view(videos, 1, 1, 1, 1)

    unit = (shifted + 1.0) / 2.0  # [0, 1]
    unit = unit * factor(config.brightness)
    grey = unit.mean(dim=(2, 3, 4), keepdim=True)
    unit = grey + (unit - grey) * factor(config.contrast)
    return unit.clamp(0.0, 1.0) * 2.0 - 1.0
