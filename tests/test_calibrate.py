"""Goal embeddings, XIRL scale and thresholds: correct by construction on synthetic and real data."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.calibrate import (
    CalibrationConfig,
    calibrate_thresholds,
    goal_embeddings,
    subtask_windows,
    xirl_distance_scale,
)
from inest_reward_node.data import load_demos
from inest_reward_node.model import load_model
from inest_reward_node.rewards import subtask_rewards
from inest_reward_node.shaping import distance_reward


def test_goal_embeddings_average_the_frames_where_subtasks_end():
    first = np.arange(20, dtype=float).reshape(10, 2)  # frame t = (2t, 2t + 1)
    second = -np.arange(16, dtype=float).reshape(8, 2)
    goals = goal_embeddings([first, second], [np.array([3, 9]), np.array([1, 7])])
    np.testing.assert_allclose(goals, [(first[3] + second[1]) / 2, (first[9] + second[7]) / 2])


def test_xirl_scale_is_one_over_the_mean_start_to_goal_distance():
    demos = [np.array([[3.0, 4.0], [0.0, 0.0]]), np.array([[0.0, 1.0], [0.0, 0.0]])]
    assert xirl_distance_scale(demos, np.zeros(2)) == pytest.approx(1 / 3.0)


def test_windows_are_the_last_hold_frames_of_each_subtask():
    assert subtask_windows(np.array([5, 9, 10]), 3) == [slice(3, 6), slice(7, 10), slice(10, 11)]
    assert subtask_windows(np.array([4, 4]), 3) == [slice(2, 5), slice(4, 5)]  # same-frame ends keep that frame


def test_thresholds_are_a_percentile_of_the_lowest_reward_in_each_window():
    ends = [np.array([3, 7]), np.array([2, 5])]
    rewards = [np.array([0, 0, -0.5, -0.2, 0, -0.9, -0.1, -0.3]), np.array([0, -0.4, -0.6, 0, -0.7, -0.8])]

    def per_subtask(_: int) -> list[np.ndarray]:
        return rewards

    # windows of 2: demo 0 -> frames 2-3 (min -0.5) and 6-7 (-0.3); demo 1 -> 1-2 (-0.6) and 4-5 (-0.8)
    lowest = calibrate_thresholds(per_subtask, ends, 2, 2, CalibrationConfig(percentile=0))
    assert lowest == pytest.approx([-0.6, -0.8])
    middle = calibrate_thresholds(per_subtask, ends, 2, 2, CalibrationConfig(percentile=50))
    assert middle == pytest.approx([-0.55, -0.55])


def test_trained_model_goals_and_thresholds_match_the_training_demos(tiny_tcc_run):
    config, run_dir = tiny_tcc_run
    model = load_model(run_dir / "model")
    demos = load_demos(config.dataset, "train", "ego", 48, progress_bar=False)
    embeddings = [model.embed(demo.frames) for demo in demos]
    for scheme in (1, 3, 6):
        goals = model.goals(scheme)
        expected = np.mean([emb[demo.ends[scheme]] for emb, demo in zip(embeddings, demos, strict=True)], axis=0)
        np.testing.assert_allclose(goals.goals, expected, rtol=1e-4, atol=1e-5)
        assert len(goals.thresholds) == scheme
        # with the default 2nd percentile, at least 87.5 % (7 of 8) of the training demos hold each threshold at its end
        for subtask in range(scheme):
            held = [
                subtask_rewards(model, emb, goals)[subtask_windows(demo.ends[scheme], 3)[subtask], subtask].min()
                >= goals.thresholds[subtask] - 1e-9
                for emb, demo in zip(embeddings, demos, strict=True)
            ]
            assert np.mean(held) >= 0.875
    start = np.stack([emb[0] for emb in embeddings])
    final = model.goals(1).goals[0]
    assert model.goals(1).distance_scale == pytest.approx(1 / np.linalg.norm(start - final, axis=1).mean(), rel=1e-4)
    # INEST measures distance in units where the mean start-to-goal distance is shaping.start_distance
    raw = np.linalg.norm(embeddings[0][0] - model.goals(3).goals[0])
    rescaled = raw * model.goals(3).distance_scale * model.shaping.start_distance
    assert subtask_rewards(model, embeddings[0][:1], model.goals(3))[0, 0] == pytest.approx(
        distance_reward(rescaled, model.shaping)
    )
