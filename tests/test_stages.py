"""RewardConfig: segment shaping, the confirmed tracker (threshold test, stage evidence, reopening),
the privileged diagnostic, the intrinsic cap, and models calibrated before any of them."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from inest_reward_node.learning.stage_fitting import fit_stage_classifier
from inest_reward_node.learning.task_stages import demo_stages, true_stages
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.methods import goal_distances
from inest_reward_node.runtime.model import MODEL_FILE, STAGE_HEADS_FILE, ModelError, load_model
from inest_reward_node.runtime.rewards import RewardScorer
from inest_reward_node.runtime.stage_classifier import StageClassifier
from inest_reward_node.runtime.trackers import ConfirmedTracker, ConfirmSettings, Evidence
from test_scorer import line_model


def run(scorer: RewardScorer, xs, stages=None) -> list:
    """Score frames at x positions on the line model, one at a time (`stages`: their true stages)."""
    return [
        scorer.score_embeddings(np.array([[x, 0.0]]), known_stages=None if stages is None else stages[i : i + 1])
        for i, x in enumerate(xs)
    ]


def approach_all_goals() -> list[float]:
    """From x = -10 towards goal 0 (x = 0), then goal 1 (10), then goal 2 (20), a few frames at each goal."""
    xs: list[float] = []
    for goal in (0.0, 10.0, 20.0):
        xs += [*np.linspace(goal - 10.0, goal, 11)[1:], goal, goal]
    return xs


def test_reward_config_validates_its_fields():
    assert RewardConfig().cap == np.inf
    for bad in (
        {"shaping": "cubic"},
        {"tracker": "vibes"},
        {"stage_source": "oracle"},
        {"hold_steps": -1},
        {"stage_confidence": 1.0},
        {"confirm_window": -1},
        {"confirm_steps": -1},
        {"instant_confidence": 0.4},
        {"instant_confidence": 1.5},
        {"intrinsic_cap": 0.0},
        {"intrinsic_cap": float("nan")},
    ):
        with pytest.raises(ValueError):
            RewardConfig(**bad)


@pytest.mark.parametrize("stage_source", ["tracker", "privileged"])
def test_segment_shaping_rises_within_every_subtask_and_never_dips_at_a_switch(stage_source):
    xs = approach_all_goals()
    config = RewardConfig(shaping="segment", stage_source=stage_source)
    scorer = RewardScorer(line_model(hold_steps=2), scheme=3, config=config)
    progress = np.clip(np.floor(np.array(xs) / 10.0) + 1, 0, 3).astype(int)  # the line's "true" stage
    steps = run(scorer, xs, progress if stage_source == "privileged" else None)
    total = np.array([s.total[0] for s in steps])
    completed = np.array([s.completed[0] for s in steps])
    assert completed[-1] == 3 and np.all(np.diff(completed) >= 0)
    assert np.all(np.diff(total) >= -1e-12)  # rises within each subtask, continuous (never dips) at a switch
    switches = [i for i, s in enumerate(steps) if s.switched[0]]
    assert len(switches) == 3
    for frame in switches:  # at a switch: bonus x (c + 1 + closeness to the next goal), above the frame before
        assert total[frame] >= total[frame - 1]
        assert total[frame] - total[frame - 1] < 1.0  # no jump of a whole bonus either
    assert total[-1] == pytest.approx(6.0) and steps[-1].shaping[0] == 0.0  # B K once done
    # before the first completion the reward is B x closeness to goal 0: 1 - d / 10
    assert total[0] == pytest.approx(2.0 * (1 - 9.0 / 10.0))


def test_segment_shaping_with_one_subtask_uses_the_single_goal():
    scorer = RewardScorer(line_model(), scheme=1, variant="inest", config=RewardConfig(shaping="segment"))
    steps = run(scorer, [-10.0, 5.0, 20.0, 20.0, 20.0])
    assert [s.total[0] for s in steps[:2]] == pytest.approx([0.0, 2.0 * (1 - 15.0 / 30.0)])
    assert steps[-1].completed[0] == 1 and steps[-1].total[0] == pytest.approx(2.0)


def test_segment_shaping_is_where_the_frame_sits_between_start_and_goal():
    scorer = RewardScorer(line_model(), scheme=3, config=RewardConfig(shaping="segment", tracker="threshold"))
    # subtask 0 runs from (-10, 0) to (0, 0): 3 from the start and 7 from the goal, off the line by 4
    off_line = scorer.score_embeddings(np.array([[-10.0 + 3.0, 4.0]]))
    s, d = np.hypot(3.0, 4.0), np.hypot(7.0, 4.0)
    assert off_line.total[0] == pytest.approx(2.0 * s / (s + d))
    # frames beyond the goal still count as close to it; the distance-based closeness would too
    assert scorer.score_embeddings(np.array([[1.0, 0.0]])).total[0] == pytest.approx(2.0 * 11.0 / 12.0)


def test_the_confirmed_tracker_does_not_fire_on_frames_the_classifier_calls_stage_0():
    model = line_model(hold_steps=2)
    never = model.subtasks[3].stage_classifier.to_dict()
    never["out_bias"] = [50.0, 0.0, 0.0, 0.0]  # stage 0, whatever the frame
    model.subtasks[3].stage_classifier = StageClassifier.from_dict(never)
    threshold = RewardScorer(model, scheme=3, config=RewardConfig(tracker="threshold"))
    at_goal = [0.0] * 30  # r(d) above the threshold: the counter completes subtask 0
    assert run(threshold, at_goal)[-1].completed[0] == 1
    honest = RewardScorer(model, scheme=3, config=RewardConfig(tracker="confirmed"))
    assert all(s.completed[0] == 0 and not s.switched[0] for s in run(honest, at_goal))


# (threshold-test rewards against goals 0 and 1, segment closeness for subtasks 0 and 1), thresholds -0.02
AT_GOAL_0 = (np.array([0.0, -0.5]), np.array([1.0, 0.0]))
MOVED_ON = (np.array([-0.5, -0.3]), np.array([0.8, 0.3]))  # left goal 0, past it: on to subtask 1
PUSHED_BACK = (np.array([-0.5, -0.6]), np.array([0.2, 0.0]))  # left goal 0, looks like subtask 0's first half


def confirmed(hold_steps: int, window: int, agree_steps: int = 0, instant: float = 1.0) -> ConfirmedTracker:
    return ConfirmedTracker([-0.02, -0.02], hold_steps, ConfirmSettings(0.5, window, agree_steps, instant))


def seen(frame: tuple[np.ndarray, np.ndarray], at_least: np.ndarray) -> Evidence:
    """A frame's evidence: its (threshold-test rewards, segment closeness) and P(stage >= j)."""
    return Evidence(*frame, at_least, None)


def test_the_confirmed_tracker_needs_the_threshold_test_and_then_the_classifier():
    says_0, says_1 = np.array([1.0, 0.1, 0.0]), np.array([1.0, 0.9, 0.1])  # P(stage >= j), j = 0..2
    tracker = confirmed(2, 3)
    assert [tracker.step(seen(AT_GOAL_0, says_0)) for _ in range(5)] == [0] * 5  # the classifier disagrees
    assert [tracker.step(seen(MOVED_ON, says_1)) for _ in range(3)] == [0, 0, 0]  # too late: the window is over
    assert [tracker.step(seen(AT_GOAL_0, says_1)) for _ in range(3)] == [0, 0, 1]  # test held twice, then agreed twice
    # the classifier may lag: it agrees after the threshold test has stopped holding, within the window
    tracker.reset()
    steps = [tracker.step(seen(AT_GOAL_0, says_0)) for _ in range(2)] + [
        tracker.step(seen(MOVED_ON, says_1)) for _ in range(2)
    ]
    assert steps == [0, 0, 0, 1] and tracker.completed == 1
    assert [tracker.step(seen(PUSHED_BACK, says_1)) for _ in range(2)] == [0, -1]  # and reopens


def test_the_confirmed_tracker_confirms_on_the_first_agreeing_frame_with_one_confirm_step():
    says_0, says_1 = np.array([1.0, 0.1, 0.0]), np.array([1.0, 0.9, 0.1])
    lags = {}
    for agree_steps in (0, 1):  # 0: as many frames as the threshold test (hold_steps 3)
        tracker = confirmed(3, 5, agree_steps)
        steps = [tracker.step(seen(AT_GOAL_0, says_0)) for _ in range(3)] + [
            tracker.step(seen(AT_GOAL_0, says_1)) for _ in range(3)
        ]
        lags[agree_steps] = steps.index(1) - 3  # frames after the classifier first agrees
    assert lags == {0: 2, 1: 0}
    scorer = RewardScorer(line_model(hold_steps=2), scheme=3, config=RewardConfig(confirm_steps=1))
    assert scorer.new_tracker().agree_steps == 1


def test_the_confirmed_tracker_confirms_clear_evidence_at_once_and_weak_evidence_after_its_streak():
    weak, clear = np.array([1.0, 0.6, 0.0]), np.array([1.0, 0.95, 0.0])  # P(stage >= j), j = 0..2
    for evidence, expected in ((weak, [0, 0, 0, 0, 1, 0]), (clear, [0, 0, 1, 0, 0, 0])):
        tracker = confirmed(3, 5, instant=0.9)
        assert [tracker.step(seen(AT_GOAL_0, evidence)) for _ in range(6)] == expected
    # before the threshold test has held, even clear evidence confirms nothing
    tracker = confirmed(3, 5, instant=0.9)
    assert [tracker.step(seen(MOVED_ON, clear)) for _ in range(4)] == [0] * 4
    assert RewardScorer(line_model(hold_steps=2), scheme=3).new_tracker().instant == 0.9  # the default


def test_the_confirmed_tracker_takes_back_a_claim_its_stage_evidence_stops_backing():
    says_1, denies_1, unsure = np.array([1.0, 0.95, 0.0]), np.array([1.0, 0.05, 0.0]), np.array([1.0, 0.3, 0.0])
    settings = ConfirmSettings(0.5, 5, 0, 0.9, retract=0.2, retract_steps=3)
    tracker = ConfirmedTracker([-0.02, -0.02], 2, settings)
    assert [tracker.step(seen(AT_GOAL_0, says_1)) for _ in range(2)] == [0, 1]
    # moved on: the embedding no longer reopens it, the stage evidence denies block 1; an unsure frame breaks the streak
    frames = [denies_1, denies_1, unsure, denies_1, denies_1, denies_1]
    assert [tracker.step(seen(MOVED_ON, at_least)) for at_least in frames] == [0, 0, 0, 0, 0, -1]
    # off by default: the same frames leave the claim standing
    latched = confirmed(2, 5, instant=0.9)
    assert [latched.step(seen(AT_GOAL_0, says_1)) for _ in range(2)] == [0, 1]
    assert [latched.step(seen(MOVED_ON, denies_1)) for _ in range(10)] == [0] * 10 and latched.completed == 1
    with pytest.raises(ValueError, match="retract_confidence"):
        RewardConfig(retract_confidence=0.5)


def test_the_confirmed_tracker_reopens_in_the_scorer():
    # it completes once the threshold test has held twice and the classifier's streak follows (its
    # instant path off; test_the_confirmed_tracker_confirms_clear_evidence_at_once... covers it)
    config = RewardConfig(instant_confidence=1.0)
    scorer = RewardScorer(line_model(hold_steps=2), scheme=3, config=config)
    steps = run(scorer, [0.0, 0.0, 0.0, 3.0, 3.0, -6.0, -6.0])  # x = 3: past goal 0; x = -6: back before it
    assert [s.completed[0] for s in steps] == [0, 0, 1, 1, 1, 1, 0]


def test_privileged_stage_follows_the_true_progress():
    scorer = RewardScorer(line_model(), scheme=3, num_envs=2, config=RewardConfig(stage_source="privileged"))
    for k, expected_switch in ((0, False), (1, True), (1, False), (3, True), (2, False)):
        parts = scorer.score_embeddings(np.array([[-5.0, 0.0], [25.0, 0.0]]), known_stages=np.array([k, k]))
        assert parts.completed.tolist() == [k, k] and parts.bonus.tolist() == [2.0 * k] * 2
        assert parts.switched.tolist() == [expected_switch] * 2
    one = RewardScorer(line_model(), scheme=1, variant="inest", config=RewardConfig(stage_source="privileged"))
    for told, completed in ((0, 0), (1, 1)):  # the caller tells the stage in the scorer's own scheme
        assert one.score_embeddings(np.array([[20.0, 0.0]]), known_stages=np.array([told])).completed[0] == completed
    with pytest.raises(ValueError, match="known_stages"):
        scorer.score_embeddings(np.zeros((2, 2)))


def test_training_refuses_the_privileged_stage_of_the_six_subtask_scheme():
    from inest_agent_node.config import TrainConfig

    with pytest.raises(ValueError, match="diagnostic"):
        TrainConfig(model="m", subtasks=6, learned_reward=RewardConfig(stage_source="privileged"))


def test_the_intrinsic_cap_bounds_the_weighted_novelty():
    intrinsic = IntrinsicConfig(mode="embedding", k=1, weight=0.2, boosted_weight=0.4, boost_steps=2)
    free = RewardScorer(line_model(), 3, intrinsic=intrinsic, config=RewardConfig(tracker="threshold"))
    capped = RewardScorer(
        line_model(), 3, intrinsic=intrinsic, config=RewardConfig(tracker="threshold", intrinsic_cap=0.5)
    )
    xs = [0.0, 30.0, -40.0, 0.1, 0.1, 0.1, 100.0]
    uncapped = np.array([s.intrinsic[0] for s in run(free, xs)])
    bounded = np.array([s.intrinsic[0] for s in run(capped, xs)])
    assert uncapped.max() > 5.0 and bounded.max() == pytest.approx(0.5)
    np.testing.assert_allclose(bounded, np.minimum(uncapped, 0.5))


def test_a_model_calibrated_before_reward_configs_loads_and_names_the_fix(tiny_tcc_run, tmp_path):
    _, run_dir = tiny_tcc_run
    old = tmp_path / "old"
    shutil.copytree(run_dir / "model", old)
    metadata = json.loads((old / MODEL_FILE).read_text())
    for goals in metadata["subtasks"].values():
        del goals["start_distances"], goals["start_embeddings"], goals["stage_classifier"], goals["stage_head"]
    (old / MODEL_FILE).write_text(json.dumps(metadata))
    (old / STAGE_HEADS_FILE).unlink()
    model = load_model(old, scheme=3)
    assert model.goals(3).start_distances is None and model.goals(3).stage_classifier is None
    assert model.goals(3).stage_head is None
    RewardScorer(model, 3, config=RewardConfig("thesis", "threshold"))  # today's reward needs none of them
    for config, missing in (
        (RewardConfig(), "start embeddings"),
        (RewardConfig("segment", "threshold"), "start embeddings"),
        (RewardConfig("thesis", "confirmed", stage_evidence="embedding"), "start embeddings"),
    ):
        with pytest.raises(ModelError, match=rf"no per-subtask {missing}|no {missing}") as error:
            RewardScorer(model, 3, config=config)
        assert "--resume" in str(error.value)
    # one subtask: the start distance is the XIRL scale's mean distance, so it is filled in
    assert model.goals(1).start_distances == pytest.approx([1.0 / model.goals(1).distance_scale])


def test_calibration_stores_start_distances_and_a_stage_classifier(tiny_tcc_run):
    config, run_dir = tiny_tcc_run
    from inest_reward_node.learning.calibrate import subtask_starts
    from inest_reward_node.learning.data import load_demos

    model = load_model(run_dir / "model")
    demos = load_demos(config.dataset, "train", "ego", 48, progress_bar=False)
    embeddings = [model.embed(demo.frames) for demo in demos]
    for scheme in (1, 3, 6):
        goals = model.goals(scheme)
        expected = [
            np.mean(
                [
                    goal_distances(emb[subtask_starts(demo.ends[scheme])[k]][None], goals)[0, k]
                    for emb, demo in zip(embeddings, demos, strict=True)
                ]
            )
            for k in range(scheme)
        ]
        assert goals.start_distances == pytest.approx(expected, rel=1e-4)
        starts = [
            np.mean([e[subtask_starts(d.ends[scheme])[k]] for e, d in zip(embeddings, demos, strict=True)], axis=0)
            for k in range(scheme)
        ]
        np.testing.assert_allclose(goals.start_embeddings, starts, rtol=1e-4, atol=1e-5)
        classifier = goals.stage_classifier
        assert classifier.num_stages == scheme + 1
        labels = np.concatenate([demo_stages(d.progress, d.labels[scheme], scheme) for d in demos])
        predicted = classifier.predict(np.concatenate(embeddings))
        # a 40-iteration encoder separates the stages only roughly. The fit weighs every stage alike
        # (fit_stage_classifier), so each stage's frames are found well above chance; where no stage
        # dominates (3 and 6 subtasks) it is also right more often than always naming the commonest
        # stage. With 1 subtask stage 0 is 99 % of the frames and the balanced fit trades a few of
        # them for the rare stage (measured: accuracy 0.98 / 0.53 / 0.50 against 0.99 / 0.37 / 0.32,
        # mean recall per stage 0.99 / 0.66 / 0.64)
        recall = [np.mean(predicted[labels == stage] == stage) for stage in np.unique(labels)]
        assert np.mean(recall) > 1.5 / len(recall)
        if scheme > 1:
            assert np.mean(predicted == labels) >= np.bincount(labels).max() / len(labels)


def test_fitting_the_stage_classifier_separates_stages_and_round_trips():
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [3.0, 0.0], [6.0, 0.0]])
    demo_x = [centres[k] + 0.3 * rng.standard_normal((50, 2)) for k in range(3)]
    demo_y = [np.full(50, k) for k in range(3)]
    negatives = [np.array([[3.0, 3.0]]) + 0.3 * rng.standard_normal((40, 2))]  # looks like nothing seen: stage 0
    classifier = fit_stage_classifier(demo_x, demo_y, 3, negatives, [np.zeros(40, int)])
    assert np.mean(classifier.predict(np.concatenate(demo_x)) == np.concatenate(demo_y)) > 0.95
    assert np.mean(classifier.predict(negatives[0]) == 0) > 0.9
    again = StageClassifier.from_dict(json.loads(json.dumps(classifier.to_dict())))
    np.testing.assert_allclose(again.probabilities(demo_x[1]), classifier.probabilities(demo_x[1]), rtol=1e-6)
    at_least = classifier.at_least(demo_x[2])
    assert np.allclose(at_least[:, 0], 1.0) and np.all(np.diff(at_least, axis=1) <= 1e-6)


def test_true_stages_are_not_latched():
    progress = np.array([0, 1, 1, 0, 1, 2, 3, 2])
    assert true_stages(progress, None, 3).tolist() == progress.tolist()
    assert true_stages(progress, None, 1).tolist() == [0, 0, 0, 0, 0, 0, 1, 0]
    held = np.array([0, 0, 1, 0, 0, 0, 0, 0], bool)
    assert true_stages(progress, held, 6).tolist() == [0, 2, 3, 0, 2, 4, 6, 4]
    labels = np.array([0, 0, 1, 1, 2, 3, 4, 5, 5], np.int8)  # a demonstration's 6-subtask labels
    demo_progress = np.array([0, 0, 0, 1, 1, 2, 2, 2, 3])
    assert demo_stages(demo_progress, labels, 6).tolist() == [0, 1, 1, 2, 3, 4, 5, 5, 6]


class FakeNode:
    """Just enough of rclpy's Node for declare_dataclass: parameters given on the command line."""

    def __init__(self, overrides: dict) -> None:
        self.overrides, self.declared = overrides, {}

    def declare_parameter(self, name, default, descriptor=None):
        self.declared[name] = default
        return type("Parameter", (), {"value": self.overrides.get(name, default)})()


def test_the_reward_node_declares_the_reward_config_as_parameters():
    pytest.importorskip("rclpy")
    from inest_reward_node.node import declare_reward_config

    node = FakeNode({})
    assert declare_reward_config(node) == RewardConfig()
    assert set(node.declared) == {f"reward.{name}" for name in RewardConfig().to_dict()}
    assert node.declared["reward.intrinsic_cap"] == float("inf")  # a double, not a None string
    chosen = declare_reward_config(
        FakeNode({"reward.shaping": "thesis", "reward.tracker": "threshold", "reward.intrinsic_cap": 0.5})
    )
    assert chosen == RewardConfig("thesis", "threshold", intrinsic_cap=0.5)
    with pytest.raises(ValueError, match="only sees images"):
        declare_reward_config(FakeNode({"reward.stage_source": "privileged"}))
    with pytest.raises(ValueError, match="unknown reward tracker"):
        declare_reward_config(FakeNode({"reward.tracker": "latched"}))


def test_serving_refuses_the_privileged_stage():
    from inest_reward_node.runtime.serving import StreamScorer

    with pytest.raises(ValueError, match="true stage"):
        StreamScorer(RewardScorer(line_model(), 3, config=RewardConfig(stage_source="privileged")))
