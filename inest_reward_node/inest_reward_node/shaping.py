"""Reward shaping of an embedding distance and the counter-based subtask tracker (thesis 4.2.3)."""

from __future__ import annotations

from collections.abc import Sequence
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


class StageTracker:
    """The stage a policy should see, moved one subtask at a time; `completed` may go down.
    Subclasses decide from each frame's evidence whether the stage moves (`step`: +1, 0, -1)."""

    def __init__(self, num_subtasks: int, hold_steps: int) -> None:
        if num_subtasks < 1:
            raise ValueError("a tracker needs at least one subtask")
        if hold_steps < 1:
            raise ValueError(f"hold_steps must be at least 1, got {hold_steps}")
        self._num_subtasks = num_subtasks
        self.hold_steps = hold_steps
        self.reset()

    def reset(self) -> None:
        self.completed = 0
        self.up_streak = 0
        self.down_streak = 0

    @property
    def num_subtasks(self) -> int:
        return self._num_subtasks

    @property
    def done(self) -> bool:
        return self.completed >= self.num_subtasks

    @property
    def current(self) -> int:
        return min(self.completed, self.num_subtasks - 1)

    def move(self, up: bool, down: bool) -> int:
        """One frame's verdicts: `up` the next stage looks reached, `down` the current one looks undone."""
        self.up_streak = self.up_streak + 1 if up and not self.done else 0
        self.down_streak = self.down_streak + 1 if down and self.completed > 0 else 0
        if self.up_streak >= self.hold_steps:
            self.completed += 1
            self.up_streak = self.down_streak = 0
            return 1
        if self.down_streak >= self.hold_steps:
            self.completed -= 1
            self.up_streak = self.down_streak = 0
            return -1
        return 0


class SubtaskTracker(StageTracker):
    """The thesis's counter: advances to the next subtask once r(d) has stayed above the current
    subtask's threshold for `hold_steps` consecutive frames (a frame below it restarts the
    count), and never goes back."""

    def __init__(self, thresholds: Sequence[float], hold_steps: int) -> None:
        if not thresholds:
            raise ValueError("a tracker needs at least one subtask threshold")
        self.thresholds = [float(value) for value in thresholds]
        super().__init__(len(self.thresholds), hold_steps)

    def update(self, reward: float) -> bool:
        """Feed the current subtask's r(d) for one frame; True when this frame completed it."""
        return self.move(not self.done and reward >= self.thresholds[self.completed], down=False) == 1
