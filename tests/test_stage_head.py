"""The pixel stage head: learns a stage that only the pixels show, is saved with the model, and feeds
the confirmed tracker when `stage_evidence` is "pixels"."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from inest_reward_node.learning.stage_fitting import boundary_frames, fit_stage_head
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.model import ModelError, load_model
from inest_reward_node.runtime.rewards import RewardScorer
from inest_reward_node.runtime.stage_head import WEIGHTS_FILE, StageHead, StageHeadConfig


def marked_frames(stages: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Noisy grey 48 px frames with one bright 8 px square per completed stage along the top."""
    frames = rng.integers(90, 130, size=(len(stages), 48, 48, 3), dtype=np.uint8)
    for index, stage in enumerate(stages):
        for mark in range(stage):
            frames[index, 4:12, 4 + 14 * mark : 12 + 14 * mark] = 250
    return frames


def test_the_head_reads_a_stage_only_the_pixels_show():
    rng = np.random.default_rng(0)
    stages = [rng.integers(0, 4, size=64) for _ in range(4)]
    config = StageHeadConfig(image_size=48, iterations=60, batch_size=32)
    head = fit_stage_head([marked_frames(s, rng) for s in stages], stages, 4, config)
    held = rng.integers(0, 4, size=200)
    at_least = head.at_least(marked_frames(held, rng))
    assert at_least.shape == (200, 4)
    np.testing.assert_allclose(at_least[:, 0], 1.0, rtol=1e-5)
    predicted = (at_least >= 0.5).sum(axis=1) - 1  # the highest stage it is confident of
    assert (predicted == held).mean() > 0.95


def test_boundary_frames_are_the_two_either_side_of_a_change_within_an_episode():
    first, second = np.array([0, 0, 0, 0, 0, 1, 1, 1, 1, 2]), np.array([0, 0, 0, 0, 0, 0])
    near = boundary_frames([first, second, np.array([1, 1, 1, 1, 3])])
    # 0 -> 1 at 5: frames 3-6; 1 -> 2 at 9, the last frame: 7-9; no change in the second episode;
    # the third (offset 16) changes at its last frame: 16 + 2, 16 + 3, 16 + 4
    assert near.tolist() == [3, 4, 5, 6, 7, 8, 9, 18, 19, 20]
    assert boundary_frames([second]).size == 0


def test_a_head_fitted_with_boundary_batches_still_reads_every_stage():
    rng = np.random.default_rng(1)
    stages = [np.sort(rng.integers(0, 4, size=64)) for _ in range(4)]  # ordered, like an episode
    config = StageHeadConfig(image_size=48, iterations=60, batch_size=32, boundary_share=0.5)
    head = fit_stage_head([marked_frames(s, rng) for s in stages], stages, 4, config)
    held = rng.integers(0, 4, size=200)
    predicted = (head.at_least(marked_frames(held, rng)) >= 0.5).sum(axis=1) - 1
    assert (predicted == held).mean() > 0.95
    with pytest.raises(ValueError, match=r"boundary_share must be in \[0, 1\)"):
        StageHeadConfig(boundary_share=1.0)


def test_heads_are_saved_with_the_model_and_used_only_when_asked(tiny_tcc_run, tmp_path):
    _, run_dir = tiny_tcc_run
    folder = run_dir / "model"
    assert (folder / WEIGHTS_FILE).is_file()
    first, second = load_model(folder), load_model(folder)
    frames = np.zeros((3, 48, 48, 3), np.uint8) + np.arange(3, dtype=np.uint8)[:, None, None, None] * 60
    for scheme in (1, 3, 6):
        np.testing.assert_array_equal(
            first.goals(scheme).stage_head.at_least(frames), second.goals(scheme).stage_head.at_least(frames)
        )
    pixels = RewardConfig(tracker="confirmed", stage_evidence="pixels")
    scorer = RewardScorer(first, 3, num_envs=3, config=pixels)
    parts = scorer.score(frames)
    assert parts.total.shape == (3,)
    with pytest.raises(ValueError, match="needs every frame's stage_evidence"):
        scorer.score_embeddings(first.embed(frames))
    assert RewardScorer(first, 3, num_envs=3).stage_evidence(frames) is not None  # the default reads pixels
    embedding = RewardConfig(stage_evidence="embedding")  # the embedding's classifier needs no frames
    assert RewardScorer(first, 3, num_envs=3, config=embedding).stage_evidence(frames) is None
    first.goals(3).stage_head = None  # a model calibrated before the head existed
    assert RewardScorer(first, 3, num_envs=3).evidence == "embedding"  # auto falls back to the classifier
    with pytest.raises(ModelError, match=r"no pixel stage head .* recalibrate"):
        RewardScorer(first, 3, config=pixels)
    without = tmp_path / "model"
    shutil.copytree(folder, without)
    (without / WEIGHTS_FILE).unlink()
    with pytest.raises(ModelError, match="cannot load the stage heads"):
        load_model(without)


def test_a_head_stored_before_its_camera_and_size_were_settings_reads_as_it_was_fitted():
    stored = StageHeadConfig(image_size=48, view=None).to_dict()
    del stored["view"], stored["image_size"]  # what a model calibrated before these settings holds
    head = StageHead.from_dict({"num_stages": 4, "config": stored})
    assert head.config.view is None and head.config.image_size == 48  # the encoder's camera, 48 px
    assert StageHead.from_dict({"num_stages": 4, "config": StageHeadConfig().to_dict()}).config == StageHeadConfig()
