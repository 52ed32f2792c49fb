"""Reward shaping of an embedding distance: the thesis's r(d) (thesis 4.2.3) and the segment closeness."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ShapingConfig:
    """r(d) = -quadratic * d^2 - linear * sqrt(d^2 + smoothing), plus `subtask_bonus` per completed subtask.

    d is measured in units where the demonstrations' mean distance from their first frame to
    the final goal is `start_distance`. A TCC embedding's scale is arbitrary (it grows the longer
    training sharpens its softmaxes: 20-35 raw units here), while the thesis's coefficients were
    tuned for one particular encoder (its hand-set threshold -0.03 sits at d = 2.45). Without the
    rescaling, r(d) spans about as much as one subtask bonus and the reward dips at every
    subtask switch; with it, r(d) spans about a tenth of a bonus, as in the thesis.
    """

    quadratic: float = 0.001
    linear: float = 0.01
    smoothing: float = 0.001
    subtask_bonus: float = 2.0  # the thesis author's code
    start_distance: float = 10.0
    hold_steps: int = 3  # consecutive frames above threshold that complete a subtask (not given in the thesis)

    def __post_init__(self) -> None:
        if min(self.quadratic, self.linear, self.smoothing) < 0:
            raise ValueError("shaping coefficients must be non-negative")
        if self.start_distance <= 0:
            raise ValueError(f"start_distance must be positive, got {self.start_distance}")
        if self.hold_steps < 1:
            raise ValueError(f"hold_steps must be at least 1, got {self.hold_steps}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def distance_reward(distance: np.ndarray | float, shaping: ShapingConfig) -> np.ndarray:
    d2 = np.square(np.asarray(distance, dtype=np.float64))
    return -shaping.quadratic * d2 - shaping.linear * np.sqrt(d2 + shaping.smoothing)


def segment_closeness(distances: np.ndarray, start_distances: np.ndarray) -> np.ndarray:
    """Where a frame sits between a subtask's start embedding and its goal, in [0, 1]: s / (s + d)
    with s the distance to the start, d to the goal (elementwise)."""
    distances, start_distances = np.asarray(distances), np.asarray(start_distances)
    return start_distances / np.maximum(start_distances + distances, 1e-12)
