"""Demonstration frames in memory, batch samplers for the two pretraining objectives, augmentation."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from inest_common.progress import track
from inest_sim_node.dataset import DemoDataset, Episode

from .encoders import resize_frames


@dataclass
class Demo:
    """What representation learning and reward evaluation need from one episode."""

    seed: int
    frames: np.ndarray  # (T+1, S, S, 3) uint8 at the encoder's input size
    rewards: np.ndarray  # (T,) the environment's dense reward
    progress: np.ndarray  # (T+1,) ordered blocks in the goal
    labels: dict[int, np.ndarray]
    ends: dict[int, np.ndarray]

    def __len__(self) -> int:
        return len(self.frames)

    @classmethod
    def from_episode(cls, episode: Episode, view: str, image_size: int) -> Demo:
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
