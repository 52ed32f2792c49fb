"""Goal embeddings, XIRL distance scale and subtask-completion thresholds from training demonstrations."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class CalibrationConfig:
    """Thresholds: for each demonstration, the lowest reward over the last `hold_steps` frames of the
    subtask (all of them must clear the threshold for the tracker to advance); the threshold is
    the `percentile`-th of those over the training demonstrations, so about (100 - percentile) %
    of them would complete the subtask where it really ends."""

    percentile: float = 2.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.percentile <= 100.0:
            raise ValueError(f"percentile must be in [0, 100], got {self.percentile}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def goal_embeddings(embeddings: Sequence[np.ndarray], ends: Sequence[np.ndarray]) -> np.ndarray:
    """Goal of subtask i = mean embedding of the frames where subtask i ends. -> (subtasks, D)."""
    return np.mean([emb[end] for emb, end in zip(embeddings, ends, strict=True)], axis=0)


def xirl_distance_scale(embeddings: Sequence[np.ndarray], final_goal: np.ndarray) -> float:
    """XIRL's normaliser: 1 / mean distance from each demonstration's first frame to the goal."""
    first = np.stack([emb[0] for emb in embeddings])
    return float(1.0 / max(np.linalg.norm(first - final_goal, axis=1).mean(), 1e-8))


def subtask_starts(ends: np.ndarray) -> np.ndarray:
    """First frame of each subtask: frame 0, then the frame after the previous subtask ended."""
    return np.concatenate([[0], np.asarray(ends[:-1]) + 1])


def subtask_windows(ends: np.ndarray, hold_steps: int) -> list[slice]:
    """The last `hold_steps` frames of each subtask, never reaching back into the previous one
    (a subtask that ends on the same frame as the one before it keeps just that frame)."""
    starts = subtask_starts(ends)
    return [
        slice(min(max(int(start), int(end) - hold_steps + 1), int(end)), int(end) + 1)
        for start, end in zip(starts, ends, strict=True)
    ]


def calibrate_thresholds(
    rewards_per_subtask: Callable[[int], Sequence[np.ndarray]],
    ends: Sequence[np.ndarray],
    num_subtasks: int,
    hold_steps: int,
    config: CalibrationConfig,
) -> list[float]:
    """`rewards_per_subtask(i)` gives, per demonstration, subtask i's reward on every frame."""
    thresholds = []
    for subtask in range(num_subtasks):
        lows = [
            float(np.min(rewards[subtask_windows(end, hold_steps)[subtask]]))
            for rewards, end in zip(rewards_per_subtask(subtask), ends, strict=True)
        ]
        thresholds.append(float(np.percentile(lows, config.percentile)))
    return thresholds
