"""Novelty memory (FIFO, k-NN) and the adaptive intrinsic weight."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.runtime.intrinsic import IntrinsicConfig, NoveltyMemory


def test_fifo_keeps_the_newest_vectors_in_order():
    memory = NoveltyMemory(dim=1, capacity=4)
    memory.add(np.arange(3, dtype=float)[:, None])
    assert len(memory) == 3 and memory.contents()[:, 0].tolist() == [0, 1, 2]
    memory.add(np.arange(3, 9, dtype=float)[:, None])
    assert len(memory) == 4  # never more than the capacity
    assert memory.contents()[:, 0].tolist() == [5, 6, 7, 8]  # oldest evicted first


def test_novelty_is_the_distance_to_the_kth_nearest_neighbour():
    rng = np.random.default_rng(0)
    stored, queries = rng.normal(size=(300, 8)), rng.normal(size=(20, 8))
    memory = NoveltyMemory(dim=8, capacity=500)
    memory.add(stored)
    for k in (1, 10):
        brute = np.sort(np.linalg.norm(queries[:, None] - stored[None], axis=-1), axis=1)[:, k - 1]
        np.testing.assert_allclose(memory.novelty(queries, k), brute, rtol=1e-4)


def test_k_is_capped_at_the_memory_size_and_an_empty_memory_gives_zero():
    memory = NoveltyMemory(dim=2, capacity=10)
    assert memory.novelty(np.ones((3, 2)), k=10).tolist() == [0.0, 0.0, 0.0]
    memory.add(np.array([[0.0, 0.0], [3.0, 4.0]]))
    assert memory.novelty(np.zeros((1, 2)), k=10)[0] == pytest.approx(5.0)  # the farthest of the two


@pytest.mark.parametrize(
    ("capacity", "prefilled"),
    [(50, 0), (50, 20), (50, 50), (12, 12), (8, 3)],  # empty, filling, full and wrapping, batch > capacity
)
def test_rounds_searched_at_once_match_novelty_then_add_round_by_round(capacity, prefilled):
    rng = np.random.default_rng(capacity + prefilled)
    stored = rng.normal(size=(prefilled + 7, 4))  # 7 more than fit once the memory wraps
    vectors = rng.normal(size=(10, 4))
    rounds = np.array([0, 0, 1, 2, 2, 2, 3, 3, 5, 5])
    at_once, round_by_round = NoveltyMemory(4, capacity), NoveltyMemory(4, capacity)
    for memory in (at_once, round_by_round):
        memory.add(stored[:prefilled])
        memory.add(stored[prefilled:][: 7 * (capacity == prefilled)])  # a full memory's ring has moved on
    expected = []
    for current in np.unique(rounds):
        members = rounds == current
        expected += round_by_round.novelty(vectors[members], k=3).tolist()
        round_by_round.add(vectors[members])
    np.testing.assert_allclose(at_once.novelty_in_rounds(vectors, rounds, k=3), expected, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(at_once.contents(), round_by_round.contents())
    with pytest.raises(ValueError, match="ascending"):
        at_once.novelty_in_rounds(vectors, rounds[::-1], k=3)


def test_weight_is_raised_for_n_steps_after_a_switch():
    config = IntrinsicConfig(weight=0.2, boosted_weight=0.4, boost_steps=3)
    steps = np.array([-1, 0, 1, 2, 3, 10])  # -1: no switch yet this episode
    assert config.weight_after(steps).tolist() == [0.2, 0.4, 0.4, 0.4, 0.2, 0.2]


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="unknown intrinsic mode"):
        IntrinsicConfig(mode="curiosity")
    with pytest.raises(ValueError, match="capacity"):
        IntrinsicConfig(capacity=0)
