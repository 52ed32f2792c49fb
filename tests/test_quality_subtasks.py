"""Per-subtask reward quality: within-subtask correlations, switch dips, tracker lag and false completions."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.learning.clips import Clip
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.quality import (
    ScorerOptionError,
    completion_lags,
    demo_quality,
    event_flags,
    false_completions,
    negative_events,
    rank_correlation,
    record_negatives,
    reward_config,
    switch_dips,
    within_subtask_spearman,
)
from inest_reward_node.runtime import rewards
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import load_model
from inest_sim_node.expert import WRONG_ORDER, ScriptedExpert

from inest_sim_node import EnvConfig, SweepToTopEnv


def test_within_subtask_spearman_matches_the_hand_computed_value():
    labels = np.array([0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3])
    values = np.array([1.0, 3.0, 2.0, 4.0, 5.0, 5.0, 5.0, 3.0, 2.0, 1.0, 7.0, 8.0])
    rho = within_subtask_spearman(values, labels, 4)
    # subtask 0: value ranks 1 3 2 4 against time ranks 1 2 3 4: sum d^2 = 2, rho = 1 - 6 * 2 / (4 * 15) = 0.8
    assert rho[0] == pytest.approx(0.8)
    assert rho[1] == 0.0  # flat shaping: no correlation
    assert rho[2] == pytest.approx(-1.0)  # moving away from the goal
    assert np.isnan(rho[3])  # two frames are too few
    # (N, subtasks): column k for subtask k
    columns = np.stack([values, -values, -values, values], axis=1)
    np.testing.assert_allclose(within_subtask_spearman(columns, labels, 4)[:3], [0.8, 0.0, 1.0])


def test_the_bonus_staircase_hides_flat_shaping_from_the_overall_spearman():
    labels = np.repeat([0, 1, 2], 10)
    shaping = np.tile(np.r_[np.zeros(5), -np.ones(5)], 3)  # flat, then worse: no progress within a subtask
    total = shaping + 2.0 * labels
    assert rank_correlation(total, np.arange(30.0)) > 0.8
    assert np.all(within_subtask_spearman(shaping, labels, 3) < 0)


def test_switch_dips_and_completion_lags():
    total = np.array([0.0, -0.1, -0.05, 1.5, 1.2, 1.3, 3.0])
    dips = switch_dips(total, [2, 6], 3)
    assert dips[0] == pytest.approx(1.5 - -0.1)  # total[3] - total[1] around the completion on frame 2
    assert np.isnan(dips[1]) and np.isnan(dips[2])  # no frame after the last one; never completed
    lags = completion_lags([2, 6], np.array([3, 5, 6]))
    assert lags[:2].tolist() == [-1.0, 1.0] and np.isnan(lags[2])


def test_false_completions_follow_the_true_ordered_progress():
    progress = np.array([0, 0, 0, 0, 1, 1, 1, 1, 1, 2])
    play = Clip(np.zeros((10, 1, 1, 3), np.uint8), progress, np.zeros(10, bool))
    # events[k]: the frames on which the tracker marked subtask k done
    # red marked done on frame 5 (really in the goal from frame 4), blue on frame 6 (not yet): blue is false
    assert false_completions([[5], [6], []], play, 3).tolist() == [False, True, False]
    assert false_completions([[2], [], []], play, 3).tolist() == [True, False, False]  # red before it counted
    assert false_completions([[5, 9], [], []], play, 3).tolist() == [False, False, False]  # reopened, done again
    assert false_completions([[1, 5], [], []], play, 3).tolist() == [True, False, False]  # once false is enough
    assert false_completions([[9]], play, 1).tolist() == [True]  # 1 subtask: done only at progress 3
    # an early completion (red 2 frames before it counts) is only early; blue on frame 6 is not (done on frame 9)
    assert false_completions([[2], [6], []], play, 3, early_frames=2).tolist() == [False, True, False]
    assert false_completions([[2], [6], []], play, 3, early_frames=3).tolist() == [False, False, False]
    held = np.array([0, 0, 1, 0, 0, 0, 0, 0, 0, 0], bool)
    grasp = Clip(play.frames, progress, held)
    # 6 subtasks: grasp red done from frame 2 on, push red from frame 4 on, grasp blue never
    assert false_completions([[2], [4], [6], [], [], []], grasp, 6).tolist() == [False, False, True] + [False] * 3
    assert false_completions([[1], [], [], [], [], []], grasp, 6).tolist()[0]


def false_flags(model, episodes, embeddings, scorer_options):
    """(episodes, 3) false completions of the 3-subtask INEST reward on negative episodes."""
    return event_flags(negative_events(model, episodes, embeddings, 3, "inest", scorer_options), episodes, 3)


@pytest.fixture(scope="module")
def tiny_model(tiny_tcc_run):
    _, run_dir = tiny_tcc_run
    return load_model(run_dir / "model")


@pytest.fixture(scope="module")
def negatives(tiny_model):
    episodes = record_negatives(tiny_model.view, tiny_model.image_size, 1)
    return episodes, {kind: [tiny_model.embed(e.frames) for e in played] for kind, played in episodes.items()}


THRESHOLD_TRACKER = {"config": RewardConfig(shaping="thesis", tracker="threshold")}  # the thesis's latched counter


def test_a_tracker_firing_on_a_random_episode_counts_as_a_false_completion(tiny_model, negatives):
    episodes, embeddings = negatives
    assert [len(episodes[kind]) for kind in ("random", "wrong_order")] == [1, 1]
    assert episodes["random"][0].progress.max() == 0  # this seed's random play places nothing
    goals = tiny_model.goals(3)
    saved = list(goals.thresholds)

    def flags(kind):
        return false_flags(tiny_model, episodes[kind], embeddings[kind], THRESHOLD_TRACKER)

    try:
        goals.thresholds = [-np.inf] * 3  # fires after hold_steps frames on anything
        assert flags("random").tolist() == [[True, True, True]]
        assert flags("wrong_order")[0, 1]  # blue "done" early on, while red is not even in the goal
        goals.thresholds = [np.inf] * 3  # never fires
        assert not flags("random").any() and not flags("wrong_order").any()
    finally:
        goals.thresholds = saved


def test_wrong_order_expert_puts_blue_in_the_goal_before_red():
    env = SweepToTopEnv(config=EnvConfig())
    blue_first, progress_at_most_red, all_in_goal = 0, 0, 0
    seeds = range(10)
    for seed in seeds:
        env.reset(seed=seed)
        expert = ScriptedExpert(seed=seed, order=WRONG_ORDER)
        entered: dict[int, int] = {}
        highest, truncated = 0, False
        while not truncated:
            _, _, _, truncated, info = env.step(expert.act(env))
            for block in np.flatnonzero(info["in_goal"]):
                entered.setdefault(int(block), env.elapsed_steps)
            highest = max(highest, info["progress"])
        blue_first += entered.get(1, np.inf) < entered.get(0, np.inf)
        progress_at_most_red += highest <= 1  # blue entered before red, so the ordered rule never counts it
        all_in_goal += bool(info["in_goal"].all())
    env.close()
    assert blue_first >= 9 and progress_at_most_red >= 9
    assert all_in_goal >= 8  # the expert does finish its (wrong) job


def test_bad_block_orders_are_refused():
    for order in ((), (0, 0, 1), (0, 3)):
        with pytest.raises(ValueError, match="order"):
            ScriptedExpert(order=order)


def test_scorer_options_reach_the_reward_scorer(tiny_model, tiny_demos, monkeypatch):
    seen = []

    class Spy(rewards.RewardScorer):
        def __init__(self, *args, **kwargs):
            seen.append(kwargs)
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(rewards, "RewardScorer", Spy)
    demo = load_demos(tiny_demos, "valid", tiny_model.view, tiny_model.image_size, limit=1, progress_bar=False)[0]
    result = demo_quality(tiny_model, demo, tiny_model.embed(demo.frames), 3, "inest", {"num_envs": 2})
    assert seen == [{"num_envs": 2}]
    assert result.within_shaping.shape == (3,) and result.dips.shape == (3,) and result.lags.shape == (3,)
    # the shaping term is the reward without the bonus
    np.testing.assert_allclose(result.replay.shaping + result.replay.bonus, result.replay.rewards)


def test_reward_settings_build_the_reward_config():
    assert reward_config({"shaping": "thesis", "tracker": "threshold"}) == RewardConfig(
        shaping="thesis", tracker="threshold"
    )
    with pytest.raises(ScorerOptionError, match=r"unknown reward setting\(s\) \['stage_evidnce'\]"):
        reward_config({"stage_evidnce": "pixels"})
    with pytest.raises(ScorerOptionError, match="unknown reward shaping 'nonsense'"):
        reward_config({"shaping": "nonsense"})


def test_the_report_replays_a_pixel_stage_tracker_on_the_frames(tiny_model, tiny_demos, negatives):
    pixels = {"config": RewardConfig(stage_evidence="pixels")}  # the default, confirmed tracker
    demo = load_demos(tiny_demos, "valid", tiny_model.view, tiny_model.image_size, limit=1, progress_bar=False)[0]
    embeddings = tiny_model.embed(demo.frames)
    result = demo_quality(tiny_model, demo, embeddings, 3, "inest", pixels)
    live = rewards.RewardScorer(tiny_model, 3, "inest", **pixels)  # frame by frame, as a camera would
    scored = np.concatenate([live.score(frame[None]).total for frame in demo.frames])
    np.testing.assert_allclose(result.reward, scored, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="needs every frame's stage_evidence"):
        rewards.replay(tiny_model, embeddings, 3, "inest", pixels)
    episodes, embedded = negatives
    flags = false_flags(tiny_model, episodes["random"], embedded["random"], pixels)
    assert flags.shape == (len(episodes["random"]), 3)


def test_the_privileged_stage_diagnostic_replays_the_true_progress(tiny_model, tiny_demos, negatives):
    privileged = {"config": RewardConfig(stage_source="privileged")}
    demo = load_demos(tiny_demos, "valid", tiny_model.view, tiny_model.image_size, limit=1, progress_bar=False)[0]
    result = demo_quality(tiny_model, demo, tiny_model.embed(demo.frames), 3, "inest", privileged)
    # the stage is the demonstration's own: each subtask completes on the frame its block counts
    assert np.all(result.lags == 0)
    np.testing.assert_array_equal(result.replay.completed, np.minimum(demo.progress, 3))
    episodes, embedded = negatives
    flags = false_flags(tiny_model, episodes["random"], embedded["random"], privileged)
    assert not flags.any()  # the true stage claims no block that is not placed
