"""The ordered success rule of "sweep to top in order" and the dense oracle reward.

The rule, precisely:
- A block's *stay* in the goal starts at the step its bounding box first lies wholly inside
  the goal strip and ends the step it no longer does; `entry_step` is the start of the
  current stay (None while outside).
- The correctly ordered prefix k is the largest k such that the first k blocks of the task
  order (red, blue, yellow) are all in the goal now and their current stays started in that
  order: entry(red) <= entry(blue) <= entry(yellow). Blocks entering in the same step are not
  out of order (a sweep may carry two at once).
- Consequences: a block that entered before its predecessor does not count until it leaves
  and re-enters after it; a counted block pushed out again drops the score to the blocks
  before it, and when it comes back later the blocks that followed it no longer count.
- Score = k / 3. The end-of-episode score is the score at the final step.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

NUM_BLOCKS = 3


def ordered_prefix(entry_steps: Sequence[int | None]) -> int:
    """Length of the correctly ordered prefix of blocks in the goal (see module doc)."""
    count = 0
    previous = -1
    for entry in entry_steps:
        if entry is None or entry < previous:
            break
        previous = entry
        count += 1
    return count


class OrderTracker:
    """Follows goal entries step by step and reports the ordered progress k."""

    def __init__(self, num_blocks: int = NUM_BLOCKS) -> None:
        self.entry_steps: list[int | None] = [None] * num_blocks

    def update(self, in_goal: Sequence[bool], step: int) -> int:
        for block, inside in enumerate(in_goal):
            if not inside:
                self.entry_steps[block] = None
            elif self.entry_steps[block] is None:
                self.entry_steps[block] = step
        return self.progress

    @property
    def progress(self) -> int:
        return ordered_prefix(self.entry_steps)

    @property
    def score(self) -> float:
        return self.progress / len(self.entry_steps)


APPROACH_REACH = 1.5  # robot-to-block distance from which the approach oracle starts paying
APPROACH_WEIGHTS = (0.5, 0.35, 0.15)  # a block's third: closeness, approach, held


def dense_reward(
    progress: int, goal_gaps: np.ndarray, gap_scale: float, approach: tuple[float, bool] | None = None
) -> float:
    """Oracle reward in [0, 1]: a third per ordered block placed, plus the current block's progress.

    The current block is the first one not yet counted; its closeness is
    1 - min(1, gap / gap_scale), gap being how far it still sticks out below the goal. Without
    `approach` that closeness is the block's progress. With `approach` = (robot-to-block
    distance, block held in the gripper) the block's third is shared by closeness, approach
    (1 - min(1, distance / APPROACH_REACH)) and holding, by APPROACH_WEIGHTS: the dense reward
    alone is flat until the block moves, so nothing leads the robot from one placed block to
    the next. Every part stays inside the block's third, so no state of a stage pays more than
    placing its block (a bonus added on top made hovering next to the last block worth more
    than finishing the task).
    """
    num_blocks = len(goal_gaps)
    if progress >= num_blocks:
        return 1.0
    closeness = 1.0 - min(1.0, float(goal_gaps[progress]) / gap_scale)
    if approach is not None:
        distance, held = approach
        parts = (closeness, 1.0 - min(1.0, distance / APPROACH_REACH), float(held))
        closeness = float(np.dot(APPROACH_WEIGHTS, parts))
    return (progress + closeness) / num_blocks
