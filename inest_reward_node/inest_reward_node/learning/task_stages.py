"""The simulator's true stage of a frame, in a subtask scheme: what calibration labels
frames with, what the reward-quality report compares the tracker against, and what the
privileged-stage diagnostic tells the scorer.
"""

from __future__ import annotations

import numpy as np
from inest_sim_node.scoring import NUM_BLOCKS
from inest_sim_node.subtasks import current_subtasks

from inest_sim_node import STATE_FIELDS

PROGRESS_FIELD = STATE_FIELDS.index("ordered_progress")  # k / 3 in the state vector


def true_stages(progress: np.ndarray, held: np.ndarray | None, scheme: int) -> np.ndarray:
    """Subtasks done on each frame right now (not latched: pushing a block out undoes its subtask);
    inest_sim_node.subtasks.current_subtasks, the rule the demonstrations' labels latch."""
    return current_subtasks(progress, held, scheme)


def demo_stages(progress: np.ndarray, labels: np.ndarray, scheme: int) -> np.ndarray:
    """A demonstration's true stage per frame. Demonstrations keep no grasp flags, so the
    6-subtask stage is read off the labels (frame t's stage is frame t + 1's label), capped by
    what the block progress allows."""
    if scheme != 6:
        return true_stages(progress, None, scheme)
    progress = np.asarray(progress, dtype=np.int64)
    stages = np.concatenate([np.asarray(labels[1:], dtype=np.int64), [int(labels[-1])]])
    stages = np.clip(stages, 2 * progress, 2 * progress + 1)
    return np.where(progress >= NUM_BLOCKS, 2 * NUM_BLOCKS, stages)


def privileged_stages(states: np.ndarray | None, scheme: int) -> np.ndarray:
    """DIAGNOSTIC: the simulator's true stage from state vectors (`ordered_progress` = k / 3)."""
    if states is None:
        raise ValueError("stage_source 'privileged' needs the environments' state vectors")
    progress = np.rint(np.asarray(states, dtype=np.float64)[:, PROGRESS_FIELD] * NUM_BLOCKS).astype(np.int64)
    return true_stages(progress, None, scheme)
