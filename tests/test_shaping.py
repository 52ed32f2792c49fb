"""r(d) values and the thesis's counter-based subtask tracker."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.runtime.shaping import ShapingConfig, distance_reward
from inest_reward_node.runtime.trackers import Evidence, ThresholdTracker


def update(tracker: ThresholdTracker, reward: float) -> bool:
    """Feed the current subtask's reward for one frame; True when this frame completed it."""
    rewards = np.full(tracker.num_subtasks, reward)
    return tracker.step(Evidence(rewards, None, None, None)) == 1


def test_distance_reward_matches_the_thesis_formula():
    shaping = ShapingConfig()
    assert distance_reward(0.0, shaping) == pytest.approx(-0.01 * np.sqrt(0.001))
    assert distance_reward(3.0, shaping) == pytest.approx(-0.009 - 0.01 * np.sqrt(9.001))
    values = distance_reward(np.array([0.0, 1.0, 2.0, 10.0]), shaping)
    assert np.all(np.diff(values) < 0)  # strictly worse with distance


def test_tracker_advances_only_after_the_hold_count():
    tracker = ThresholdTracker([-0.1, -0.2], hold_steps=3)
    assert [update(tracker, r) for r in (-0.05, -0.05)] == [False, False]
    assert tracker.completed == 0
    assert update(tracker, -0.05) is True
    assert (tracker.completed, tracker.current) == (1, 1)
    # the second subtask has its own threshold
    assert [update(tracker, r) for r in (-0.15, -0.15, -0.15)] == [False, False, True]
    assert tracker.done and tracker.current == 1
    assert update(tracker, 0.0) is False


def test_tracker_count_restarts_on_a_dip_and_on_reset():
    tracker = ThresholdTracker([-0.1], hold_steps=3)
    for reward in (-0.05, -0.05, -0.5, -0.05, -0.05):
        update(tracker, reward)
    assert tracker.completed == 0 and tracker.up_streak == 2
    update(tracker, -0.05)
    assert tracker.done
    tracker.reset()
    assert (tracker.completed, tracker.up_streak, tracker.done) == (0, 0, False)


def test_shaping_config_rejects_bad_values():
    with pytest.raises(ValueError, match="hold_steps"):
        ShapingConfig(hold_steps=0)
    with pytest.raises(ValueError, match="at least one"):
        ThresholdTracker([], 3)
