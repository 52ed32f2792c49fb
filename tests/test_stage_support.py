"""The demonstrations' support of each stage: evidence of a stage above the completed ones counts
only on frames that look like demonstrations of that stage."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from inest_reward_node.learning.config import CalibrationConfig
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.pretrain import recalibrate
from inest_reward_node.learning.stage_fitting import fit_stage_support
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import ModelError, load_model
from inest_reward_node.runtime.rewards import RewardScorer, replay
from inest_reward_node.runtime.stage_support import StageSupport, gate


def test_the_radius_covers_the_quantile_of_held_out_demonstration_frames_and_far_frames_fall_outside():
    rng = np.random.default_rng(0)
    demos = [rng.normal(0, 1, (40, 4)) + np.repeat(np.arange(4), 10)[:, None] * 10 for _ in range(10)]
    stages = [np.repeat(np.arange(4), 10) for _ in demos]
    support = fit_stage_support(demos, stages, 4, quantile=0.9, references=100)
    assert len(support.references) == 3 and all(len(ref) == 40 * 10 // 4 for ref in support.references)
    near = demos[0][stages[0] == 2]  # stage-2 frames of a demonstration
    assert support.supported(near)[:, 2].mean() >= 0.9 and support.supported(near)[:, 0].all()
    far = near + 100.0
    assert not support.supported(far)[:, 1:].any()
    with pytest.raises(ValueError, match="stage_support_quantile"):
        CalibrationConfig(stage_support_quantile=1.5)


def test_the_gate_withholds_only_stages_above_the_completed_ones():
    at_least = np.array([1.0, 0.95, 0.9, 0.8])
    supported = np.array([True, True, False, True])
    np.testing.assert_allclose(gate(at_least, supported, completed=1), [1.0, 0.95, 0.0, 0.0])
    np.testing.assert_allclose(gate(at_least, supported, completed=2), at_least)  # stage 2 is already held
    np.testing.assert_allclose(gate(at_least, np.ones(4, bool), completed=0), at_least)


def test_the_support_is_fitted_at_calibration_kept_beside_the_weights_and_read_by_the_tracker(
    tiny_tcc_run, tiny_demos, tmp_path
):
    config, run = tiny_tcc_run
    calibration = dataclasses.replace(
        config.calibration,
        random_episodes=2,
        wrong_order_episodes=1,
        stage_support_quantile=0.95,
        stage_support_references=50,
        stage_head=dataclasses.replace(config.calibration.stage_head, iterations=0),
    )
    model = recalibrate(dataclasses.replace(config, calibration=calibration), run / "model", tmp_path / "s", False)
    reloaded = load_model(tmp_path / "s" / "model")
    support = reloaded.goals(3).stage_support
    assert (tmp_path / "s" / "model" / "stage_support.safetensors").exists()
    assert [len(ref) for ref in support.references] == [len(ref) for ref in model.goals(3).stage_support.references]
    np.testing.assert_allclose(support.radii, model.goals(3).stage_support.radii)
    demo = load_demos(tiny_demos, "valid", "ego", model.image_size, progress_bar=False)[0]
    embeddings = model.embed(demo.frames)
    gated = replay(reloaded, embeddings, 3, scorer_options={"config": RewardConfig(stage_support=True)}).parts
    free = replay(reloaded, embeddings, 3).parts
    assert np.all(gated.completed <= free.completed)  # the gate only ever withholds
    nowhere = StageSupport([ref[:1] + 1e6 for ref in support.references], [0.0] * 3, 0.95)
    reloaded.goals(3).stage_support = nowhere  # no frame is like a demonstration: no stage is ever reached
    withheld = replay(reloaded, embeddings, 3, scorer_options={"config": RewardConfig(stage_support=True)}).parts
    assert withheld.completed.max() == 0
    with pytest.raises(ModelError, match="no stage support"):
        RewardScorer(load_model(run / "model"), 3, config=RewardConfig(stage_support=True))
