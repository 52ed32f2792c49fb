"""The causal forward filter over stages, and the stage's confidence the reward reports."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardScorer, replay
from inest_reward_node.runtime.stage_filter import StageFilter, exactly, transition_matrix


def test_one_confident_frame_moves_the_belief_a_little_a_run_of_frames_moves_it_one_stage_at_a_time():
    stage_filter = StageFilter(4, advance=0.05, regress=0.005, temperature=0.5)
    says_done = np.array([0.01, 0.01, 0.01, 0.97])  # a frame that looks like all three blocks placed
    belief = stage_filter.update(says_done)
    assert belief.argmax() == 0 and belief[3] < 0.01  # two stages ahead of anything before it: ignored
    stage_filter.reset()
    says_one = np.array([0.02, 0.96, 0.01, 0.01])
    assert stage_filter.update(says_one)[1] < 0.5  # one frame of stage 1 is not enough
    beliefs = [stage_filter.update(says_one) for _ in range(4)]
    assert beliefs[-1].argmax() == 1 and beliefs[-1][1] > 0.9  # a few frames in a row are
    climbing = [stage_filter.update(says_done).argmax() for _ in range(40)]
    assert climbing[-1] == 3 and climbing.index(3) >= 2  # two stages up takes frames, through stage 2's mass
    np.testing.assert_allclose(transition_matrix(4, 0.05, 0.005).sum(axis=1), 1.0)
    np.testing.assert_allclose(exactly(np.array([1.0, 0.7, 0.2, 0.1])), [0.3, 0.5, 0.1, 0.1])
    with pytest.raises(ValueError, match="advance"):
        StageFilter(4, advance=0.6, regress=0.5, temperature=1.0)
    with pytest.raises(ValueError, match="filter_temperature"):
        RewardConfig(stage_filter="forward", filter_temperature=0.0)


def test_the_scorer_reports_how_sure_its_stage_is_and_filters_when_asked(tiny_tcc_run, tiny_demos):
    from inest_reward_node.learning.data import load_demos

    model = load_model(tiny_tcc_run[1] / "model")
    demo = load_demos(tiny_demos, "train", "ego", model.image_size, progress_bar=False)[0]
    embeddings = model.embed(demo.frames)
    plain = replay(model, embeddings, 3, frames=demo.frames).parts
    assert np.all((plain.confidence >= 0) & (plain.confidence <= 1))
    options = {"config": RewardConfig(stage_filter="forward")}
    filtered = replay(model, embeddings, 3, scorer_options=options, frames=demo.frames).parts
    assert np.all((filtered.confidence >= 0) & (filtered.confidence <= 1))
    assert not np.allclose(filtered.confidence, plain.confidence)  # the filter changed the evidence read
    thesis = replay(model, embeddings, 3, scorer_options={"config": RewardConfig(tracker="threshold")}).parts
    assert np.isnan(thesis.confidence).all()  # no stage evidence read: no confidence
    with pytest.raises(ValueError, match="threshold tracker reads none"):
        RewardScorer(model, 3, config=RewardConfig(tracker="threshold", stage_filter="forward"))
