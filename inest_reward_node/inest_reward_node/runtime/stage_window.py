"""The stage over a causal window of frames: P(stage | the embeddings of frame t and of a few
frames before it), SARM's window without its future frames. One egocentric frame facing the wall
cannot show which blocks are placed; the frames before it can, and the window reads them.

The window is frames t - offset for each of `offsets` (0 first), each clamped to the episode's
first frame, so a reward for frame t reads frames up to t only. The classifier is the embedding
stage classifier's MLP (stage_classifier.py) on the concatenated embeddings; it is fitted at
calibration (learning/calibrate.py) on the demonstrations, the labelled negatives, and rewound and
reordered demonstrations (learning/demo_negatives.py), which need no labels of their own.
"""

from __future__ import annotations

import itertools
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from .stage_classifier import StageClassifier

DEFAULT_OFFSETS = (0, 2, 4, 8, 16)  # frames back; sparse, to see further for the same input size


def check_offsets(offsets: tuple[int, ...]) -> None:
    if not offsets or offsets[0] != 0 or any(b <= a for a, b in itertools.pairwise(offsets)):
        raise ValueError(f"window offsets must start at 0 and increase, got {list(offsets)}")


def window_features(embeddings: np.ndarray, offsets: tuple[int, ...]) -> np.ndarray:
    """(T, D) embeddings of one episode -> (T, len(offsets) * D): frame t's window, causal."""
    steps = np.arange(len(embeddings))
    return np.concatenate([embeddings[np.maximum(steps - offset, 0)] for offset in offsets], axis=1)


class WindowHistory:
    """One stream's recent embeddings, for its window at the newest frame."""

    def __init__(self, offsets: tuple[int, ...]) -> None:
        self.offsets = offsets
        self.frames: deque[np.ndarray] = deque(maxlen=offsets[-1] + 1)

    def reset(self) -> None:
        self.frames.clear()

    def push(self, embedding: np.ndarray) -> np.ndarray:
        """Add the stream's newest embedding; its window's features (earlier frames clamped)."""
        self.frames.append(np.asarray(embedding, np.float32))
        newest = len(self.frames) - 1
        return np.concatenate([self.frames[max(newest - offset, 0)] for offset in self.offsets])


@dataclass
class StageWindow:
    """The window's offsets and the classifier on its features; stored in model.json."""

    offsets: tuple[int, ...]
    classifier: StageClassifier

    def __post_init__(self) -> None:
        check_offsets(self.offsets)

    @property
    def num_stages(self) -> int:
        return self.classifier.num_stages

    def history(self) -> WindowHistory:
        return WindowHistory(self.offsets)

    def to_dict(self) -> dict[str, Any]:
        return {"offsets": list(self.offsets), "classifier": self.classifier.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StageWindow:
        return cls(tuple(int(offset) for offset in data["offsets"]), StageClassifier.from_dict(data["classifier"]))
