"""The stage classifier refitted during training on the agent's own frames: self negatives (claims
the tracker never confirms, no labels) and labelled rollouts (a round of the agent's episodes in
which the reward claimed a stage, labelled with their true stage)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from inest_agent_node.train import Trainer
from inest_experiments.summary import reward_supervision
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.labelled_rollouts import LABELLED_FILE, RolloutLabelling
from inest_reward_node.learning.self_negatives import CONFIRM_WITHIN, SelfNegatives
from inest_reward_node.learning.stage_refit import REFIT_MODEL_DIR, StageRefit
from inest_reward_node.learning.task_stages import PROGRESS_FIELD
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardParts, RewardScorer, Steps
from inest_sim_node.env import STATE_FIELDS
from small_training import small_train_config

from inest_experiments import reevaluate


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


def parts(stages: list[int], marker: float) -> RewardParts:
    """Scored rows claiming `stages`, each embedding filled with `marker`."""
    rows = np.zeros(len(stages))
    return RewardParts(
        rows, rows, rows, rows, rows, np.array(stages), rows.astype(bool), np.full((len(stages), 4), marker), rows
    )


def steps(progress: list[int], ends: list[bool]) -> Steps:
    """One vector step of len(progress) environments whose blocks placed in order are `progress`."""
    states = np.zeros((len(progress), len(STATE_FIELDS)))
    states[:, PROGRESS_FIELD] = np.array(progress) / 3
    return Steps(envs=np.arange(len(progress)), episode_ends=np.array(ends), states=states)


def test_a_claim_the_tracker_never_confirms_becomes_a_negative_one_it_confirms_does_not(tiny_tcc_run, tiny_demos):
    model = load_model(tiny_tcc_run[1] / "model")
    scorer = RewardScorer(model, 3, config=RewardConfig(stage_evidence="embedding"))
    negatives = SelfNegatives(scorer, num_envs=1)
    refit = StageRefit(scorer, tiny_demos, negatives, None)
    calibration = model.metadata.calibration  # its labelled episodes are refitted on too, not dropped
    assert len(refit.labelled_stages) == calibration["random_episodes"] + calibration["wrong_order_episodes"] > 0
    calibration["clips"] = ["nowhere.npz"]
    with pytest.raises(ValueError, match=r"calibrated on the clip file nowhere\.npz, which is not here"):
        StageRefit(scorer, tiny_demos, negatives, None)
    calibration["clips"] = []
    # frame 1 claims red (confirmed at frame 3); frame 5 claims blue, never confirmed
    claims = [0, 1, 1, 1, 1, 2] + [2] * (CONFIRM_WITHIN + 2)
    stages = [0, 0, 0, 1, 1, 1] + [1] * (CONFIRM_WITHIN + 2)
    scorer.classifier = Claims(claims)
    for frame, stage in enumerate(stages):
        negatives.observe(np.array([0]), parts([stage], float(frame)), np.array([False]))
    kept = [(float(embedding[0]), label) for embedding, label in negatives.negatives]
    assert kept[0] == (5.0, 1)  # blue claimed at frame 5 while the tracker kept stage 1
    assert all(label == 1 for _, label in kept) and 1.0 not in [frame for frame, _ in kept]
    resumed = SelfNegatives(scorer, num_envs=1)
    resumed.restore(negatives.state())  # from a checkpoint: a refit after a resume forgets none
    assert [(float(embedding[0]), label) for embedding, label in resumed.negatives] == kept


def test_a_labelling_round_keeps_whole_episodes_the_reward_claimed_a_stage_in_with_their_true_stages(
    tiny_tcc_run, tiny_demos, tmp_path
):
    labelling = RolloutLabelling(3, num_envs=2, label_at=(100,), per_round=1)
    labelling.observe(steps([0, 0], [True, False]), parts([1, 1], 0.0))  # no round open yet: nothing kept
    labelling.open_rounds(99)
    assert labelling.owed == 0 and not labelling.round_complete()
    labelling.open_rounds(100)
    labelling.observe(steps([0, 0], [True, True]), parts([1, 1], 1.0))  # both end: episodes begin after
    labelling.observe(steps([1, 0], [False, False]), parts([0, 0], 2.0))
    labelling.observe(steps([1, 0], [False, True]), parts([1, 0], 3.0))  # env 1 never claimed: not kept
    assert labelling.episodes == [] and labelling.wanted == 1
    labelling.observe(steps([1, 1], [True, False]), parts([0, 1], 4.0))  # env 0 claimed red at 3.0
    [(embeddings, truth)] = labelling.episodes
    assert embeddings[:, 0].tolist() == [2.0, 3.0, 4.0] and truth.tolist() == [1, 1, 1]
    assert labelling.round_complete() and labelling.wanted == 0
    labelling.observe(steps([2, 1], [True, True]), parts([2, 2], 5.0))  # the round is done: no more
    assert len(labelling.episodes) == 1

    model = load_model(tiny_tcc_run[1] / "model")
    model.goals(3).thresholds = [-10.0] * 3  # calibrated as low as no labelled episode would leave them
    scorer = RewardScorer(model, 3, config=RewardConfig(stage_evidence="embedding"))
    # a whole demonstration labelled "nothing placed": the loop's strongest case against the thresholds
    demo = load_demos(tiny_demos, "train", model.view, model.image_size, 1, progress_bar=False)[0]
    labelling.episodes = [(model.embed(demo.frames), np.zeros(len(demo.frames), int))]
    refit = StageRefit(scorer, tiny_demos, None, labelling)
    frames = refit.refit(tmp_path, [scorer])
    assert (frames.self_negatives, frames.labelled_episodes) == (0, 1) and not labelling.round_complete()
    refitted = load_model(tmp_path / REFIT_MODEL_DIR)
    supervision = refitted.metadata.supervision
    assert supervision["negatives"]["policy_rollouts"] == {"episodes": 1, "labelled_by": "simulator"}
    assert supervision["labelled_episodes"] == model.metadata.supervision["labelled_episodes"] + 1
    raised = refitted.goals(3).thresholds
    assert min(raised) > -10.0  # raised against the episode, as far as the demonstrations allow
    assert scorer.trackers[0].thresholds == raised and scorer.goals.thresholds == raised  # read from the next frame
    again = RolloutLabelling(3, num_envs=2, label_at=(100,), per_round=1)
    again.restore(tmp_path)  # a resumed run keeps the person's labels and owes no refit for them
    assert (tmp_path / LABELLED_FILE).exists() and not again.episodes[0][1].any()
    again.open_rounds(100)
    assert not again.round_complete() and again.wanted == 0


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
    assert [steps for steps, _, _ in results["stage_refits"]] == [100, 200, 300, 400]
    checkpoint = json.loads((run / "checkpoint" / "checkpoint.json").read_text())
    assert checkpoint["stage_refits"] == results["stage_refits"]  # a resumed run keeps its record
    with np.load(run / "checkpoint" / "self-negatives.npz") as kept:  # and its self negatives
        assert len(kept["stages"]) == results["stage_refits"][-1][1]
    if any(count for _, count, _ in results["stage_refits"]):
        refitted = load_model(run / REFIT_MODEL_DIR)
        assert "self_negatives" in refitted.metadata.supervision["negatives"]
        assert trainer.reward_env.reward.classifier is trainer.stage_readers()[1].classifier  # one classifier
    assert reevaluate.main([str(run), "--episodes", "2"]) == 0
    again = json.loads((run / "evaluations" / "test-2.json").read_text())
    assert again["evaluation"] == results["final_evaluation"]


def test_the_labels_spent_in_the_loop_count_in_the_runs_labelling_budget(tiny_tcc_run):
    model = str(tiny_tcc_run[1] / "model")
    fitted = reward_supervision({"reward": "inest", "model": model})["labelled_episodes"]
    config = {"reward": "inest", "model": model, "label_at": [20_000, 80_000], "label_episodes": 5}
    assert reward_supervision(config)["labelled_episodes"] == fitted + 10
    with pytest.raises(ValueError, match=r"label_at must list distinct positive steps in ascending order"):
        small_train_config(label_at=(200, 100), refit_demos="demos", model=model)
    with pytest.raises(ValueError, match=r"needs the inest reward and refit_demos"):
        small_train_config(label_at=(100,), model=model)
