"""Per-frame subtask labels for the three decompositions the thesis studies (1, 3, 6 subtasks).

A frame's label is the subtask being worked on when the frame was reached: the frame on
which subtask i completes still carries label i, the next frame carries i + 1. So the last
frame labelled i is where subtask i ends, which is what goal embeddings are averaged over.
- 1 subtask: the whole task (XIRL); it completes when all three blocks count.
- 3 subtasks: one per block in task order; block k completes when the ordered progress reaches k + 1.
- 6 subtasks: per block, reach/grasp (completes when the block first sits in the gripper
  while it is the current block) then push (completes when it counts in the goal).
"""

from __future__ import annotations

import numpy as np

from .world import BLOCK_COLOURS

SCHEMES = (1, 3, 6)

DESCRIPTIONS: dict[int, tuple[str, ...]] = {
    1: ("The robot pushes the red, then the blue, then the yellow block into the green zone",),
    3: tuple(f"The robot pushes the {c} block into the green zone" for c in BLOCK_COLOURS),
    6: tuple(
        text
        for c in BLOCK_COLOURS
        for text in (
            f"The robot reaches and grasps the {c} block",
            f"The robot pushes the {c} block into the green zone",
        )
    ),
}


def current_subtasks(progress: np.ndarray, held: np.ndarray | None, scheme: int) -> np.ndarray:
    """Number of subtasks done at each frame right now (not latched: a block pushed out again
    undoes its subtask).

    `progress[t]` is the ordered block count at frame t, `held[t]` whether the current
    block sits in the gripper at frame t (needed by the 6-subtask scheme only: its reach/grasp
    subtask stays done until the progress changes).
    """
    progress = np.asarray(progress, dtype=np.int64)
    num_blocks = len(BLOCK_COLOURS)
    if scheme == 1:
        return (progress >= num_blocks).astype(np.int64)
    if scheme == 3:
        return progress.copy()
    if scheme != 6:
        raise ValueError(f"unknown subtask scheme {scheme}; expected one of {SCHEMES}")
    if held is None:
        raise ValueError("the 6-subtask scheme needs the per-frame grasp flags")
    reached = np.zeros_like(progress)
    latched = False
    for t in range(len(progress)):
        if t > 0 and progress[t] != progress[t - 1]:
            latched = False
        latched = latched or bool(held[t])
        reached[t] = 1 if latched and progress[t] < num_blocks else 0
    return 2 * progress + reached


def completed_subtasks(progress: np.ndarray, held: np.ndarray, scheme: int) -> np.ndarray:
    """Number of subtasks completed at each frame (never decreasing), as the demonstrations label them."""
    return np.maximum.accumulate(current_subtasks(progress, held, scheme))


def subtask_labels(progress: np.ndarray, held: np.ndarray, scheme: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame labels in [0, scheme) and, per subtask, the frame on which it ends.

    A subtask that never completes ends on the last frame.
    """
    done = completed_subtasks(progress, held, scheme)
    labels = np.minimum(np.concatenate([[0], done[:-1]]), scheme - 1).astype(np.int8)
    last = len(done) - 1
    ends = np.array(
        [int(np.argmax(done >= i + 1)) if done[-1] >= i + 1 else last for i in range(scheme)], dtype=np.int32
    )
    return labels, ends


def labels_from_ends(ends: list[int], length: int) -> tuple[np.ndarray, dict[int, np.ndarray], dict[int, np.ndarray]]:
    """A recorded demonstration of `length` frames, cut where a person says its subtasks end: its
    ordered progress per frame and its labels and ends in every scheme those ends determine. Three
    ends (one per block) give the 1- and 3-subtask schemes, six (per block: reached and grasped,
    then pushed in) all three. The ends must rise strictly and lie on the episode's frames."""
    ends_array = np.asarray(ends, dtype=np.int64)
    num_blocks = len(BLOCK_COLOURS)
    if len(ends_array) not in (num_blocks, 2 * num_blocks):
        raise ValueError(f"{len(ends_array)} subtask ends; expected {num_blocks} or {2 * num_blocks}")
    if np.any(np.diff(ends_array) <= 0) or ends_array[0] < 0 or ends_array[-1] >= length:
        raise ValueError(f"subtask ends {ends_array.tolist()} must rise strictly within frames 0..{length - 1}")
    pushed = ends_array if len(ends_array) == num_blocks else ends_array[1::2]
    progress = (np.arange(length)[:, None] >= pushed[None, :]).sum(axis=1).astype(np.int8)
    held = np.zeros(length, dtype=bool)  # grasped on the frame its reach/grasp subtask ends: enough to latch it
    if len(ends_array) == 2 * num_blocks:
        held[ends_array[0::2]] = True
    schemes = SCHEMES if len(ends_array) == 2 * num_blocks else tuple(s for s in SCHEMES if s != 6)
    labels, scheme_ends = {}, {}
    for scheme in schemes:
        labels[scheme], scheme_ends[scheme] = subtask_labels(progress, held, scheme)
    return progress, labels, scheme_ends
