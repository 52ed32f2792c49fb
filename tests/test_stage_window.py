"""The stage over a causal window of frames, and the negatives the demonstrations give it with no
labels of their own (rewound and reordered demonstrations)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from inest_reward_node.learning.config import CalibrationConfig
from inest_reward_node.learning.demo_negatives import demo_negatives, reordered, rewound
from inest_reward_node.learning.pretrain import recalibrate
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import ModelError, load_model
from inest_reward_node.runtime.rewards import RewardScorer, replay
from inest_reward_node.runtime.stage_window import WindowHistory, window_features


def test_demonstrations_rewound_and_reordered_keep_their_frames_and_stages():
    rng = np.random.default_rng(0)
    for _ in range(20):
        order = rewound(100, rng)
        turn = int(order.argmax())
        assert np.array_equal(order[: turn + 1], np.arange(turn + 1)) and turn >= 50
        assert len(order) > turn + 1 and np.all(np.diff(order[turn:]) == -1)  # then backwards
    stages = np.repeat([0, 1, 2, 3], [10, 20, 30, 40])
    order = reordered(stages, rng)
    assert sorted(order) == list(range(100)) and not np.array_equal(stages[order], np.sort(stages[order]))
    assert reordered(np.zeros(50, int), rng) is None  # one segment: nothing to reorder
    episodes = demo_negatives([stages, stages[:60]], 3)
    assert len(episodes) == 6 and [demo for demo, _ in episodes] == [0, 0, 1, 1, 0, 0]


def test_a_window_reads_its_frame_and_frames_before_it_never_after():
    embeddings = np.arange(12, dtype=np.float32).reshape(6, 2)
    features = window_features(embeddings, (0, 1, 3))
    assert features[4].tolist() == [8, 9, 6, 7, 2, 3] and features[0].tolist() == [0, 1] * 3  # clamped at 0
    history = WindowHistory((0, 1, 3))
    streamed = [history.push(row) for row in embeddings]
    np.testing.assert_array_equal(np.stack(streamed), features)  # streaming gives the same windows
    history.reset()
    np.testing.assert_array_equal(history.push(embeddings[5]), np.tile(embeddings[5], 3))
    with pytest.raises(ValueError, match="start at 0 and increase"):
        CalibrationConfig(window_offsets=(1, 2))


def test_the_window_classifier_is_fitted_at_calibration_and_read_by_the_tracker(tiny_tcc_run, tiny_demos, tmp_path):
    from inest_reward_node.learning.data import load_demos

    config, run = tiny_tcc_run
    calibration = dataclasses.replace(
        config.calibration,
        random_episodes=2,
        wrong_order_episodes=1,
        window_offsets=(0, 2, 4),
        demo_negatives=4,
        stage_head=dataclasses.replace(config.calibration.stage_head, iterations=0),
    )
    model = recalibrate(dataclasses.replace(config, calibration=calibration), run / "model", tmp_path / "w", False)
    reloaded = load_model(tmp_path / "w" / "model")
    assert reloaded.goals(3).stage_window.offsets == (0, 2, 4)
    np.testing.assert_allclose(
        reloaded.goals(3).stage_window.classifier.out_weight, model.goals(3).stage_window.classifier.out_weight
    )
    demo = load_demos(tiny_demos, "train", "ego", model.image_size, progress_bar=False)[0]
    embeddings = model.embed(demo.frames)
    options = {"config": RewardConfig(stage_evidence="window")}
    whole = replay(reloaded, embeddings, 3, scorer_options=options).parts
    cut = replay(reloaded, embeddings[:40], 3, scorer_options=options).parts
    assert np.all((whole.confidence >= 0) & (whole.confidence <= 1))
    np.testing.assert_allclose(cut.confidence, whole.confidence[:40])  # causal: later frames change nothing
    assert RewardScorer(reloaded, 3, config=RewardConfig(stage_evidence="window")).evidence == "window"
    with pytest.raises(ModelError, match="no window stage classifier"):
        RewardScorer(load_model(run / "model"), 3, config=RewardConfig(stage_evidence="window"))
