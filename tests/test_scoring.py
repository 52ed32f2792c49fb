"""The ordered score rule, as pure logic and on real physics."""

from __future__ import annotations

import numpy as np
import pytest
from inest_sim_node.scoring import OrderTracker, dense_reward, ordered_prefix

RED, BLUE, YELLOW = 0, 1, 2


@pytest.mark.parametrize(
    ("entries", "expected"),
    [
        ([None, None, None], 0),
        ([3, None, None], 1),
        ([3, 7, None], 2),
        ([3, 7, 9], 3),
        ([3, 3, 9], 3),  # red and blue swept in together: not out of order
        ([None, 4, 6], 0),  # blue and yellow in, red never
        ([5, 4, None], 1),  # blue entered before red: blue does not count
        ([2, 8, 5], 2),  # yellow entered before blue
    ],
)
def test_ordered_prefix(entries, expected):
    assert ordered_prefix(entries) == expected


def test_out_of_order_block_counts_only_after_reentering():
    tracker = OrderTracker()
    assert tracker.update([False, True, False], step=1) == 0  # blue first: wrong order
    assert tracker.update([True, True, False], step=2) == 1  # red now in, blue's stay began earlier
    assert tracker.update([True, False, False], step=3) == 1  # blue pushed out
    assert tracker.update([True, True, False], step=4) == 2  # blue back in, after red
    assert tracker.score == pytest.approx(2 / 3)


def test_pushed_out_block_drops_the_score_and_its_successors():
    tracker = OrderTracker()
    tracker.update([True, False, False], 1)
    tracker.update([True, True, False], 2)
    assert tracker.update([True, True, True], 3) == 3
    assert tracker.update([False, True, True], 4) == 0  # red pushed out: nothing counts
    # red comes back, but blue and yellow entered before it: only red counts
    assert tracker.update([True, True, True], 5) == 1


def test_dense_reward_is_monotone_in_progress_and_closeness():
    gaps_far = np.array([1.0, 1.0, 1.0])
    gaps_near = np.array([0.2, 1.0, 1.0])
    assert dense_reward(0, gaps_far, 2.0) < dense_reward(0, gaps_near, 2.0) < dense_reward(1, gaps_far, 2.0)
    assert dense_reward(3, gaps_far, 2.0) == 1.0
    assert dense_reward(0, np.array([5.0, 0, 0]), 2.0) == 0.0


def _settle(world, steps=2):
    world.apply_action(np.zeros(3))
    for _ in range(steps):
        world.step()


def _in_goal_xy(world, x):
    return (x, world.config.goal_bottom + world.config.block_side)


def test_score_on_real_physics_wrong_order_then_right_order(env):
    env.reset(seed=1)
    world = env.world
    world.place_block(BLUE, _in_goal_xy(world, 0.3))  # blue enters first
    env.step(np.zeros(3))
    world.place_block(RED, _in_goal_xy(world, -0.4))
    _, _, _, _, info = env.step(np.zeros(3))
    assert list(info["in_goal"]) == [True, True, False]
    assert info["score"] == pytest.approx(1 / 3)
    world.place_block(BLUE, (0.3, 0.0))  # out again ...
    env.step(np.zeros(3))
    world.place_block(BLUE, _in_goal_xy(world, 0.3))  # ... and back in, after red
    world.place_block(YELLOW, _in_goal_xy(world, 0.8))
    _, _, _, _, info = env.step(np.zeros(3))
    assert info["score"] == pytest.approx(1.0)
    assert info["is_success"]


def test_block_sticking_out_of_the_goal_does_not_count(env):
    env.reset(seed=2)
    world = env.world
    half = world.config.block_side / 2
    world.place_block(RED, (0.0, world.config.goal_bottom + half - 0.02))  # 2 cm outside
    _, _, _, _, info = env.step(np.zeros(3))
    assert not info["in_goal"][RED]
    assert info["score"] == 0.0
