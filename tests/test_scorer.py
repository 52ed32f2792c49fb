"""The learned reward for N environments: subtask bonus, terminal reward, intrinsic bonus, batching."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.encoders import EncoderConfig
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import ModelError, ModelMetadata, RewardModel, build_network, load_model
from inest_reward_node.runtime.rewards import THESIS_REWARD, RewardScorer
from inest_reward_node.runtime.shaping import ShapingConfig, distance_reward
from inest_reward_node.runtime.stage_classifier import StageClassifier

GOALS = [[0.0, 0.0], [10.0, 0.0], [20.0, 0.0]]


def line_classifier(boundaries: list[float], sharpness: float = 5.0) -> StageClassifier:
    """Stage j beats stage j - 1 exactly where x > boundaries[j - 1]: logit_j = s (j x - sum of the
    first j boundaries), with the hidden layer (relu(x), relu(-x)) carrying x."""
    stages = np.arange(len(boundaries) + 1, dtype=np.float32)
    slope = sharpness * stages
    return StageClassifier(
        mean=np.zeros(2),
        scale=np.ones(2),
        hidden_weight=np.array([[1.0, -1.0], [0.0, 0.0]]),
        hidden_bias=np.zeros(2),
        out_weight=np.stack([slope, -slope]),
        out_bias=-sharpness * np.concatenate([[0.0], np.cumsum(boundaries)]),
    )


def line_model(hold_steps: int = 2, calibrated: bool = True) -> RewardModel:
    """A 2-D embedding space with three goals on a line; distance_scale x start_distance = 1, so d is raw.
    Subtask k starts 10 before its goal (at the previous goal, or x = -10 for the first); the stage
    classifier says stage k + 1 once x passes 10 k - 1 (stage 1 of the 1-subtask scheme past 19).
    `calibrated=False`: a model.json from before start distances/embeddings and stage classifiers."""
    encoder = EncoderConfig(embedding_dim=2, image_size=32)
    shaping = ShapingConfig(hold_steps=hold_steps)
    one = {"goals": GOALS[-1:], "thresholds": [-0.02], "distance_scale": 0.1}
    three = {"goals": GOALS, "thresholds": [-0.02, -0.02, -0.02], "distance_scale": 0.1}
    if calibrated:
        one |= {
            "start_distances": [30.0],
            "start_embeddings": [[-10.0, 0.0]],
            "stage_classifier": line_classifier([19.0]).to_dict(),
        }
        three |= {
            "start_distances": [10.0, 10.0, 10.0],
            "start_embeddings": [[-10.0, 0.0], [0.0, 0.0], [10.0, 0.0]],
            "stage_classifier": line_classifier([-1.0, 9.0, 19.0]).to_dict(),
        }
    metadata = {
        "method": "tcc",
        "view": "ego",
        "encoder": encoder.to_dict(),
        "shaping": shaping.to_dict(),
        "subtasks": {"1": one, "3": three},
    }
    return RewardModel(build_network("tcc", encoder), ModelMetadata.from_dict(metadata))


def at(x: float) -> np.ndarray:
    return np.array([[x, 0.0]])


def test_bonus_per_completed_subtask_and_constant_reward_after_the_last():
    scorer = RewardScorer(line_model(hold_steps=2), scheme=3, config=THESIS_REWARD)
    far = scorer.score_embeddings(at(5.0))
    assert far.total[0] == pytest.approx(distance_reward(5.0, scorer.model.shaping))
    assert (far.subtask[0], far.bonus[0]) == (0, 0.0)
    scorer.score_embeddings(at(0.0))  # first frame at goal 1: holding, not yet complete
    done_first = scorer.score_embeddings(at(0.0))
    assert done_first.switched[0] and done_first.subtask[0] == 1
    assert done_first.bonus[0] == 2.0
    assert done_first.total[0] == pytest.approx(distance_reward(0.0, scorer.model.shaping) + 2.0)
    next_goal = scorer.score_embeddings(at(0.0))  # now measured against goal 2, 10 away
    assert next_goal.total[0] == pytest.approx(distance_reward(10.0, scorer.model.shaping) + 2.0)
    for x in (10.0, 10.0, 20.0, 20.0):
        parts = scorer.score_embeddings(at(x))
    assert parts.completed[0] == 3
    for x in (20.0, -50.0):  # after the last subtask: the bonus alone, wherever the frame is
        parts = scorer.score_embeddings(at(x))
        assert parts.total[0] == 6.0 and parts.shaping[0] == 0.0
    scorer.reset(0)
    assert scorer.score_embeddings(at(20.0)).completed[0] == 0  # the tracker restarts per episode


def test_xirl_reward_is_the_scaled_distance_to_the_final_goal():
    scorer = RewardScorer(line_model(), scheme=1, variant="xirl")
    assert scorer.score_embeddings(at(0.0)).total[0] == pytest.approx(-0.1 * 20.0)
    with pytest.raises(ModelError, match="one goal embedding"):
        RewardScorer(line_model(), scheme=3, variant="xirl")


def test_intrinsic_bonus_uses_the_current_subtasks_memory_and_the_boost_window():
    intrinsic = IntrinsicConfig(mode="embedding", k=1, weight=0.2, boosted_weight=0.4, boost_steps=2)
    scorer = RewardScorer(line_model(hold_steps=1), scheme=3, intrinsic=intrinsic, config=THESIS_REWARD)
    assert scorer.score_embeddings(at(3.0)).intrinsic[0] == 0.0  # empty memory
    assert scorer.score_embeddings(at(7.0)).intrinsic[0] == pytest.approx(0.2 * 4.0)
    switch = scorer.score_embeddings(at(0.0))  # completes subtask 1 (hold 1); novelty judged in subtask 1
    assert switch.switched[0] and switch.intrinsic[0] == pytest.approx(0.2 * 3.0)
    first = scorer.score_embeddings(at(5.0))  # subtask 2's memory is empty
    assert first.intrinsic[0] == 0.0
    boosted = scorer.score_embeddings(at(8.0))
    assert boosted.intrinsic[0] == pytest.approx(0.4 * 3.0)  # 1 step after the switch
    normal = scorer.score_embeddings(at(8.5))
    assert normal.intrinsic[0] == pytest.approx(0.2 * 0.5)  # 2 steps after: back to 0.2
    scorer.reset(0)
    again = scorer.score_embeddings(at(3.0))
    assert again.intrinsic[0] == pytest.approx(0.2 * 0.0)  # memories persist across episodes
    assert len(scorer.memories[0]) == 4 and len(scorer.memories[1]) == 3


# recorded with the scorer as it was before RewardConfig existed (the thesis reward, threshold tracker)
TODAY_XS = [5.0, 1.0, 0.1, 0.0, 0.05, 4.0, 9.0, 9.9, 10.0, 10.1, 3.0, 18.0, 19.9, 20.0, 20.0, 20.0, -5.0, 20.0]
TODAY = {
    "total": [-0.07518091734037219, 0.7884649054575844, 2.9767219693570723, 1.7998645103465427, 1.8213617732173684,
              3.503834214528647, 3.778464867310612, 5.17672187398964, 3.7998645103465427, 3.842858325316271,
              6.380883389988587, 5.575683779394064, 5.956721797695695, 6.396893379374201, 6.039958474040032, 6.0,
              12.0, 6.0],
    "shaping": [-0.07518091734037219, -0.011535094542415593, -0.0032780497164141406, -0.20013548965345718,
                 -0.1986382181399582, -0.0961657854713528, -0.011535094542415593, -0.0032780497164141397,
                 -0.20013548965345718, -0.19714594893280596, -0.4591167625993038, -0.024316220605936245,
                 -0.0032780497164141458, -0.0031066206257996712, 0.0, 0.0, 0.0, 0.0],
    "bonus": [0.0, 0.0, 2.0, 2.0, 2.0, 2.0, 2.0, 4.0, 4.0, 4.0, 4.0, 4.0, 4.0, 6.0, 6.0, 6.0, 6.0, 6.0],
    "intrinsic": [0.0, 0.8, 0.9800000190734863, 0.0, 0.01999999135732651, 1.6, 1.7899999618530273, 1.1799999237060548,
                  0.0, 0.04000427424907685, 2.8400001525878906, 1.6, 1.9599998474121094, 0.4, 0.03995847404003144,
                  0.0, 6.0, 0.0],
    "subtask": [0, 0, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2],
    "completed": [0, 0, 1, 1, 1, 1, 1, 2, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3],
}  # fmt: skip


def test_the_thesis_config_reproduces_the_rewards_from_before_reward_configs():
    intrinsic = IntrinsicConfig(mode="embedding", k=2, boost_steps=3)
    for model in (line_model(hold_steps=2), line_model(hold_steps=2, calibrated=False)):
        scorer = RewardScorer(model, scheme=3, intrinsic=intrinsic, config=RewardConfig("thesis", "threshold"))
        steps = [scorer.score_embeddings(np.array([[x, 0.3]])) for x in TODAY_XS]
        for name, expected in TODAY.items():
            # float32 nearest-neighbour distances round differently on different CPUs (1.5e-5 seen)
            np.testing.assert_allclose([getattr(s, name)[0] for s in steps], expected, rtol=1e-6, atol=1e-4)
        assert [int(s.switched[0]) for s in steps] == [0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0]


def test_state_intrinsic_bonus_needs_states():
    scorer = RewardScorer(line_model(), scheme=3, intrinsic=IntrinsicConfig(mode="state", k=1))
    scorer.score_embeddings(at(0.0), states=np.array([[0.0, 0.0, 0.0]]))
    parts = scorer.score_embeddings(at(0.0), states=np.array([[0.0, 3.0, 4.0]]))
    assert parts.intrinsic[0] == pytest.approx(0.2 * 5.0)
    with pytest.raises(ValueError, match="state vectors"):
        scorer.score_embeddings(at(0.0))


def test_batched_scoring_matches_one_environment_at_a_time(tiny_tcc_run):
    config, run_dir = tiny_tcc_run
    model = load_model(run_dir / "model")
    from inest_reward_node.learning.data import load_demos

    demos = load_demos(config.dataset, "train", "ego", 48, limit=3, progress_bar=False)
    length = min(len(demo) for demo in demos)
    batched = RewardScorer(model, scheme=3, num_envs=3)
    singles = [RewardScorer(model, scheme=3) for _ in demos]
    for t in range(length):
        together = batched.score(np.stack([demo.frames[t] for demo in demos]))
        for index, (scorer, demo) in enumerate(zip(singles, demos, strict=True)):
            alone = scorer.score(demo.frames[t : t + 1])
            assert together.total[index] == pytest.approx(alone.total[0], abs=1e-5)
            assert together.subtask[index] == alone.subtask[0]
    with pytest.raises(ValueError, match="one frame per environment"):
        batched.score(demos[0].frames[:2])
