"""Novelty memory (FIFO, k-NN) and the adaptive intrinsic weight."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.intrinsic import IntrinsicConfig, NoveltyMemory


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


def test_weight_is_raised_for_n_steps_after_a_switch():
    config = IntrinsicConfig(weight=0.2, boosted_weight=0.4, boost_steps=3)
    steps = np.array([-1, 0, 1, 2, 3, 10])  # -1: no switch yet this episode
    assert config.weight_after(steps).tolist() == [0.2, 0.4, 0.4, 0.4, 0.2, 0.2]


def test_config_rejects_bad_values():
    with pytest.raises(ValueError, match="unknown intrinsic mode"):
        IntrinsicConfig(mode="curiosity")
    with pytest.raises(ValueError, match="capacity"):
        IntrinsicConfig(capacity=0)
