"""Stage evidence over time: a causal forward filter over the stages 0..K.

One frame cannot say which blocks are placed when it shows none of them (an egocentric camera
facing the wall), and a policy finds such frames: single-frame stage evidence is fooled in a
third to a half of its episodes (docs/reports/reward-signal.md). The stage is observable from the
frames before it. The filter keeps a belief over the stages and, per frame, (1) moves it with a
near-monotone prior, a stage advancing by one with probability `advance` per frame and falling
back by one with `regress` (a block pushed back out), then (2) weighs it by the frame's stage
probabilities raised to `temperature` (below 1: one frame counts for less). A confident frame
that contradicts the last frames moves the belief a little; a run of frames moves it, and the
stage can only climb through each stage in turn. Frame t's belief reads frames up to t only.
"""

from __future__ import annotations

import numpy as np

FLOOR = 1e-6  # no frame rules a stage out completely: the belief can always recover


def transition_matrix(num_stages: int, advance: float, regress: float) -> np.ndarray:
    """(K + 1, K + 1) P(next stage = j | stage = i): stay, one up with `advance`, one down with `regress`."""
    matrix = np.zeros((num_stages, num_stages))
    for stage in range(num_stages):
        up = advance if stage + 1 < num_stages else 0.0
        down = regress if stage > 0 else 0.0
        matrix[stage, stage] = 1.0 - up - down
        if up:
            matrix[stage, stage + 1] = up
        if down:
            matrix[stage, stage - 1] = down
    return matrix


class StageFilter:
    """The belief over stages of one stream; `update` takes a frame's P(stage = j), returns the
    filtered P(stage = j) after it."""

    def __init__(self, num_stages: int, advance: float, regress: float, temperature: float) -> None:
        if not 0 < advance < 1 or not 0 <= regress < 1 or advance + regress >= 1:
            raise ValueError(f"need 0 < advance, 0 <= regress and advance + regress < 1, got {advance}, {regress}")
        if not 0 < temperature <= 1:
            raise ValueError(f"temperature must be in (0, 1], got {temperature}")
        self.transition = transition_matrix(num_stages, advance, regress)
        self.temperature = temperature
        self.reset()

    def reset(self) -> None:
        """A new episode starts in stage 0."""
        self.belief = np.zeros(len(self.transition))
        self.belief[0] = 1.0

    def update(self, probabilities: np.ndarray) -> np.ndarray:
        predicted = self.belief @ self.transition
        weighed = predicted * np.maximum(np.asarray(probabilities, dtype=np.float64), FLOOR) ** self.temperature
        self.belief = weighed / weighed.sum()
        return self.belief.copy()


def exactly(at_least: np.ndarray) -> np.ndarray:
    """(..., K + 1) P(stage >= j) -> P(stage = j)."""
    at_least = np.asarray(at_least)
    return at_least - np.concatenate([at_least[..., 1:], np.zeros_like(at_least[..., :1])], axis=-1)
