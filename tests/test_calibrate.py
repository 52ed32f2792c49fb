"""Goal embeddings, XIRL scale and thresholds: correct by construction on synthetic and real data."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.learning.calibrate import (
    calibrate_thresholds,
    goal_embeddings,
    highest_held,
    start_distances,
    subtask_starts,
    subtask_windows,
    xirl_distance_scale,
)
from inest_reward_node.learning.config import CalibrationConfig
from inest_reward_node.learning.data import load_demos
from inest_reward_node.runtime.methods import subtask_rewards
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.shaping import distance_reward


def test_goal_embeddings_average_the_frames_where_subtasks_end():
    first = np.arange(20, dtype=float).reshape(10, 2)  # frame t = (2t, 2t + 1)
    second = -np.arange(16, dtype=float).reshape(8, 2)
    goals = goal_embeddings([first, second], [np.array([3, 9]), np.array([1, 7])])
    np.testing.assert_allclose(goals, [(first[3] + second[1]) / 2, (first[9] + second[7]) / 2])


def test_xirl_scale_is_one_over_the_mean_start_to_goal_distance():
    demos = [np.array([[3.0, 4.0], [0.0, 0.0]]), np.array([[0.0, 1.0], [0.0, 0.0]])]
    assert xirl_distance_scale(demos, np.zeros(2)) == pytest.approx(1 / 3.0)


def test_start_distances_are_the_mean_distance_to_each_goal_where_its_subtask_starts():
    first = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])  # subtasks end on frames 1 and 3
    second = np.array([[0.0, 2.0], [1.0, 0.0], [3.0, 0.0]])  # ... and on frames 0 and 2
    goals = np.array([[1.0, 0.0], [3.0, 0.0]])
    starts = start_distances([first, second], [np.array([1, 3]), np.array([0, 2])], goals)
    # subtask 0 starts on frame 0 (distances 1 and sqrt 5), subtask 1 on frames 2 and 1 (distances 1 and 2)
    assert starts == pytest.approx([(1 + np.sqrt(5)) / 2, 1.5])


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


def test_highest_held_is_the_best_level_kept_for_the_hold_count():
    rewards = np.array([0.0, 5, 5, 5, 1, 9, 9])
    assert highest_held(rewards, 3) == 5.0
    assert highest_held(rewards, 2) == 9.0
    assert highest_held(rewards[:2], 3) == -np.inf


def test_random_play_raises_a_threshold_it_would_cross_but_not_beyond_what_demos_reach():
    # one subtask ending on frame 3; the demos' end windows (hold 2) bottom out at -0.5 and -0.6
    ends = [np.array([3]), np.array([3])]
    demos = [np.array([-0.9, -0.8, -0.5, -0.1, -0.1, -0.1]), np.array([-0.9, -0.7, -0.6, -0.2, -0.2, -0.2])]
    # random play holds -0.4 (twice in 10 episodes), -0.45 (once) and never more otherwise
    negatives = [np.array([-0.9, -0.4, -0.4])] * 2 + [np.array([-0.45, -0.45, -0.9])] + [np.array([-0.9] * 3)] * 7

    def thresholds(config: CalibrationConfig, random_play: list[np.ndarray]) -> float:
        return calibrate_thresholds(lambda _: demos, ends, 1, 2, config, lambda _: random_play)[0]

    demos_only = CalibrationConfig(percentile=0)
    assert calibrate_thresholds(lambda _: demos, ends, 1, 2, demos_only) == pytest.approx([-0.6])
    # at most 10 % of random episodes may cross: the 90th percentile of what they hold
    assert thresholds(CalibrationConfig(percentile=0, false_fire_rate=0.1), negatives) == pytest.approx(-0.4)
    assert thresholds(CalibrationConfig(percentile=0, false_fire_rate=0.3), negatives) == pytest.approx(-0.45)
    # random play that crosses everything the demos reach: capped where demos still complete
    crossing = [np.array([0.5, 0.5, 0.5])] * 10
    capped = thresholds(CalibrationConfig(percentile=0, demo_pass_rate=1.0, late_frames=0), crossing)
    assert capped == pytest.approx(-0.6)  # over frames 0-3 demo 0 holds -0.5, demo 1 -0.6: both must complete
    # frames after a subtask's end count as completing on time within late_frames
    late = thresholds(CalibrationConfig(percentile=0, demo_pass_rate=1.0, late_frames=2), crossing)
    assert late == pytest.approx(-0.2)


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
        # at least 7 of 8 training demos complete each subtask on time: they hold the threshold over
        # the subtask's last frames (the demonstrations' percentile), or within its span and the
        # `late_frames` after it (the ceiling on what random play may raise it to)
        late = config.calibration.late_frames
        for subtask in range(scheme):
            on_time = []
            for emb, demo in zip(embeddings, demos, strict=True):
                rewards = subtask_rewards(model, emb, goals)[:, subtask]
                end_window = rewards[subtask_windows(demo.ends[scheme], 3)[subtask]].min()
                start, end = subtask_starts(demo.ends[scheme])[subtask], demo.ends[scheme][subtask]
                span = highest_held(rewards[start : end + 1 + late], 3)
                on_time.append(max(end_window, span) >= goals.thresholds[subtask] - 1e-9)
            assert np.mean(on_time) >= 0.875
    start = np.stack([emb[0] for emb in embeddings])
    final = model.goals(1).goals[0]
    assert model.goals(1).distance_scale == pytest.approx(1 / np.linalg.norm(start - final, axis=1).mean(), rel=1e-4)
    # INEST measures distance in units where the mean start-to-goal distance is shaping.start_distance
    raw = np.linalg.norm(embeddings[0][0] - model.goals(3).goals[0])
    rescaled = raw * model.goals(3).distance_scale * model.shaping.start_distance
    assert subtask_rewards(model, embeddings[0][:1], model.goals(3))[0, 0] == pytest.approx(
        distance_reward(rescaled, model.shaping)
    )
