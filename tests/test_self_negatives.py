"""Self negatives: the agent's own frames whose stage claims the tracker never confirms become
negatives the stage classifier is refitted on during training, with no labels."""

from __future__ import annotations

import json

import numpy as np
import pytest
from inest_agent_node.self_negatives import CONFIRM_WITHIN, REFIT_MODEL_DIR, SelfNegatives
from inest_agent_node.train import Trainer
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardParts, RewardScorer
from small_training import small_train_config

from inest_agent_node import reevaluate


class Claims:
    """A stand-in classifier: P(stage >= j) that claims `claims[frame]` stages."""

    def __init__(self, claims: list[int]) -> None:
        self.claims, self.frame = claims, 0

    def at_least(self, embeddings: np.ndarray) -> np.ndarray:
        rows = []
        for _ in embeddings:
            claim = self.claims[self.frame]
            rows.append([1.0] + [1.0 if j <= claim else 0.0 for j in range(1, 4)])
            self.frame += 1
        return np.array(rows)


def parts(stage: int, marker: float) -> RewardParts:
    one = np.zeros(1)
    return RewardParts(one, one, one, one, one, np.array([stage]), one.astype(bool), np.full((1, 4), marker), one)


def test_a_claim_the_tracker_never_confirms_becomes_a_negative_one_it_confirms_does_not(tiny_tcc_run, tiny_demos):
    model = load_model(tiny_tcc_run[1] / "model")
    scorer = RewardScorer(model, 3, config=RewardConfig(stage_evidence="embedding"))
    negatives = SelfNegatives(scorer, tiny_demos, num_envs=1)
    calibration = model.metadata.calibration  # its labelled episodes are refitted on too, not dropped
    assert len(negatives.labelled_stages) == calibration["random_episodes"] + calibration["wrong_order_episodes"] > 0
    calibration["clips"] = ["nowhere.npz"]
    with pytest.raises(ValueError, match=r"calibrated on the clip file nowhere\.npz, which is not here"):
        SelfNegatives(scorer, tiny_demos, num_envs=1)
    calibration["clips"] = []
    # frame 1 claims red (confirmed at frame 3); frame 5 claims blue, never confirmed
    claims = [0, 1, 1, 1, 1, 2] + [2] * (CONFIRM_WITHIN + 2)
    stages = [0, 0, 0, 1, 1, 1] + [1] * (CONFIRM_WITHIN + 2)
    scorer.classifier = Claims(claims)
    for frame, stage in enumerate(stages):
        negatives.observe(np.array([0]), parts(stage, float(frame)), np.array([False]))
    kept = [(float(embedding[0]), label) for embedding, label in negatives.negatives]
    assert kept[0] == (5.0, 1)  # blue claimed at frame 5 while the tracker kept stage 1
    assert all(label == 1 for _, label in kept) and 1.0 not in [frame for frame, _ in kept]


def test_training_refits_the_classifier_and_a_re_evaluation_reads_the_refitted_one(tiny_tcc_run, tiny_demos, tmp_path):
    config = small_train_config(
        reward="inest",
        model=str(tiny_tcc_run[1] / "model"),
        learned_reward=RewardConfig(stage_evidence="embedding"),
        refit_every=100,
        refit_demos=str(tiny_demos),
        total_steps=400,
        final_eval_episodes=2,
    )
    run = tmp_path / "run"
    trainer = Trainer(config, run, progress_bar=False)
    trainer.train()
    results = json.loads((run / "results.json").read_text())
    assert [steps for steps, _ in results["stage_refits"]] == [100, 200, 300, 400]
    if any(count for _, count in results["stage_refits"]):
        refitted = load_model(run / REFIT_MODEL_DIR)
        assert "self_negatives" in refitted.metadata.supervision["negatives"]
        assert trainer.reward_env.reward.classifier is trainer.stage_readers()[1].classifier  # one classifier
    assert reevaluate.main([str(run), "--episodes", "2"]) == 0
    again = json.loads((run / "evaluations" / "test-2.json").read_text())
    assert again["evaluation"] == results["final_evaluation"]
