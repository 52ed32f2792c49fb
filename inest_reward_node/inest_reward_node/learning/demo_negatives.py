"""Negatives that need no labels, built from the demonstrations alone (as ReWiND builds them):
frame orders no demonstration shows, each frame keeping its own true stage.

- rewound: a demonstration played up to a point and then backwards, so its blocks leave the
  strip again: frames seen before at a higher stage are followed by frames of a lower one.
- reordered: a demonstration's subtask segments in a shuffled order, so a window holds frames of
  a later stage before frames of an earlier one.

A classifier of one frame learns nothing from them (each frame and its label are a
demonstration's); the window stage classifier (runtime/stage_window.py), which reads the frames
before the current one, learns that earlier frames of a higher stage do not make the current one
that stage. Each episode is an index sequence into its demonstration's frames.
"""

from __future__ import annotations

import numpy as np


def rewound(length: int, rng: np.random.Generator) -> np.ndarray:
    """Frames 0..turn, then back down to some earlier frame; turn in the second half."""
    turn = int(rng.integers(length // 2, length))
    back = int(rng.integers(max(turn // 4, 1), turn + 1))
    return np.concatenate([np.arange(turn + 1), np.arange(turn - 1, turn - back - 1, -1)])


def reordered(stages: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
    """The demonstration's stage segments in a shuffled order other than its own; None when it
    has one segment only."""
    bounds = np.flatnonzero(np.diff(stages)) + 1
    segments = np.split(np.arange(len(stages)), bounds)
    if len(segments) < 2:
        return None
    order = np.arange(len(segments))
    while np.array_equal(order, np.arange(len(segments))):
        order = rng.permutation(len(segments))
    return np.concatenate([segments[index] for index in order])


def demo_negatives(stages: list[np.ndarray], count: int, seed: int = 0) -> list[tuple[int, np.ndarray]]:
    """`count` rewound and `count` reordered episodes, as (demonstration index, frame indices),
    from demonstrations taken in turn."""
    rng = np.random.default_rng(seed)
    episodes: list[tuple[int, np.ndarray]] = []
    for number in range(count):
        demo = number % len(stages)
        episodes.append((demo, rewound(len(stages[demo]), rng)))
        order = reordered(stages[demo], rng)
        if order is not None:
            episodes.append((demo, order))
    return episodes
