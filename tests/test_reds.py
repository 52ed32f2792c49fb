"""REDS baseline (no CLIP): its losses, pretraining through the same command, the model folder,
the reds reward with REDS's own subtask inference, training on it, and wrong-method models."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from inest_reward_node.learning.config import PretrainConfig
from inest_reward_node.learning.data import load_demos, sample_reds_batch, segmentation
from inest_reward_node.learning.losses import pearson_distance, supervised_contrastive_loss
from inest_reward_node.learning.objectives import RedsObjective
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.encoders import EncoderConfig
from inest_reward_node.runtime.methods import default_variant
from inest_reward_node.runtime.model import (
    ModelError,
    ModelMetadata,
    build_network,
    load_model,
    read_model_metadata,
    save_model,
)
from inest_reward_node.runtime.reds import RedsConfig, infer_subtasks, subtask_scores
from inest_reward_node.runtime.rewards import RewardScorer, replay
from inest_reward_node.runtime.shaping import ShapingConfig
from small_training import small_train_config

TINY_REDS = RedsConfig(frames_per_batch=8, canonical_samples=2)


# --- the losses and the inference, on their own ------------------------------------------------
def test_pearson_distance_ignores_positive_affine_maps_and_flips_for_negative_ones():
    a = torch.tensor([0.0, 1.0, 1.0, 2.0, 3.0])
    assert float(pearson_distance(a, 2.5 * a + 3.0)) == pytest.approx(0.0, abs=1e-4)
    assert float(pearson_distance(a, -a)) == pytest.approx(1.0, abs=1e-4)


def test_supervised_contrastive_loss_is_low_when_features_sit_with_their_label():
    labels = torch.tensor([0, 0, 1, 1])
    aligned = torch.tensor([[1.0, 0.0], [1.0, 0.01], [0.0, 1.0], [0.01, 1.0]])
    crossed = aligned[[0, 2, 1, 3]]
    assert supervised_contrastive_loss(aligned, labels, 0.1) < supervised_contrastive_loss(crossed, labels, 0.1)


def test_subtask_inference_is_the_most_similar_embedding_biased_towards_earlier_subtasks():
    embeddings = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    features = np.array([[2.0, 0.1], [0.1, 3.0], [-1.0, 0.0], [1.0, 1.0]])
    assert infer_subtasks(features, embeddings, 0.0).tolist() == [0, 1, 2, 0]
    # (cos + 1) / 2 + eps (K - 1 - k): equally similar to 0 and 1, the earlier one wins
    assert subtask_scores(np.array([[0.5, 0.5, 0.5]]), 0.05).round(3).tolist() == [[0.85, 0.8, 0.75]]
    near_one = np.array([[0.05, 1.0]])  # slightly more like subtask 1, but not by the bias
    assert infer_subtasks(near_one, embeddings, 0.0).tolist() == [1]
    assert infer_subtasks(near_one, embeddings, 0.5).tolist() == [0]


def test_reds_batches_carry_segmentation_labels_and_rewards(tiny_demos):
    demos = load_demos(tiny_demos, "train", "ego", 48, limit=3, progress_bar=False)
    labels, targets = segmentation(demos[0], 3)
    assert labels.min() == 0 and labels.max() == 2 and np.all(np.diff(targets) >= 0)
    assert targets[0] == 0 and targets[-1] == 3  # a demonstration completes all three subtasks
    assert np.all(targets >= labels) and np.all(targets <= labels + 1)
    batch = sample_reds_batch(demos, 3, 8, 2, 20, np.random.default_rng(0))
    assert batch.frames.shape == (8, 48, 48, 3) and batch.canonical_frames.shape == (8, 2, 48, 48, 3)
    assert batch.labels.shape == batch.targets.shape == batch.next_labels.shape == (8,)
    assert batch.canonical_labels.shape == batch.canonical_targets.shape == (8, 2)
    assert np.all(batch.next_labels >= batch.labels)  # the later frame is never in an earlier subtask


def test_reds_objective_trains_encoder_head_and_subtask_embeddings(tiny_demos):
    demos = load_demos(tiny_demos, "train", "ego", 48, limit=3, progress_bar=False)
    encoder = EncoderConfig(image_size=48)
    config = PretrainConfig(dataset=str(tiny_demos), method="reds", encoder=encoder, reds=TINY_REDS)
    network = build_network("reds", config.encoder, reds=config.reds)
    loss = RedsObjective(config, network).loss(demos, np.random.default_rng(0), torch.Generator().manual_seed(0))
    assert torch.isfinite(loss)
    loss.backward()
    for parameter in (network.subtask_embeddings, network.head[0].weight, next(network.encoder.parameters())):
        assert parameter.grad is not None and parameter.grad.abs().sum() > 0
    assert {"videos_per_batch", "pairs_per_batch", "holdr"}.isdisjoint(config.settings_that_matter())
    assert "reds" in config.settings_that_matter()
    assert "reds" not in PretrainConfig(dataset="").settings_that_matter()  # TCC runs resume as before
    with pytest.raises(ValueError, match=r"reds\.frames_per_batch"):
        RedsConfig(frames_per_batch=1)


# --- a pretrained REDS model ------------------------------------------------------------------
@pytest.fixture(scope="module")
def reds_model_dir(tiny_demos, tmp_path_factory):
    out = tmp_path_factory.mktemp("reds")
    command = [
        Path(sys.executable).parent / "inest-pretrain",
        tiny_demos,
        "--out",
        out,
        "--method",
        "reds",
        "--image-size",
        "48",
        "--iterations",
        "12",
        "--reds-frames-per-batch",
        "8",
        "--reds-canonical-samples",
        "2",
        "--validate-every",
        "6",
        "--learning-rate",
        "0.001",
        "--random-episodes",
        "3",
        "--wrong-order-episodes",
        "1",
        "--stage-head-iterations",
        "0",
    ]
    run = subprocess.run(
        command, capture_output=True, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"}, check=False
    )
    assert run.returncode == 0, run.stderr
    assert "reds" in run.stdout and "goals for 3 subtasks" in run.stdout
    return out / "model"


def test_reds_model_round_trips_through_its_folder(reds_model_dir, tiny_demos, tmp_path):
    model = load_model(reds_model_dir, view="ego", image_size=48, scheme=3)
    assert model.method == "reds" and sorted(model.subtasks) == [3]
    assert model.metadata.reds == RedsConfig(frames_per_batch=8, canonical_samples=2)
    document = json.loads((reds_model_dir / "model.json").read_text())
    assert document["method"] == "reds" and document["reds"]["subtasks"] == 3 and document["holdr"] is None
    # the goals are the learned subtask embeddings
    np.testing.assert_allclose(model.goals(3).goals, model.reds_subtask_embeddings(), atol=1e-6)
    assert len(model.goals(3).thresholds) == 3 and model.goals(3).stage_classifier is not None
    frames = load_demos(tiny_demos, "valid", "ego", 48, limit=1, progress_bar=False)[0].frames
    embeddings = model.embed(frames)
    rewards = model.reds_rewards(embeddings, model.goals(3).goals)
    assert rewards.shape == (len(frames), 3) and np.isfinite(rewards).all()
    save_model(tmp_path / "copy", model.network, read_model_metadata(reds_model_dir))
    copy = load_model(tmp_path / "copy")
    np.testing.assert_allclose(copy.embed(frames), embeddings, atol=1e-5)
    np.testing.assert_allclose(copy.reds_rewards(embeddings, copy.goals(3).goals), rewards, atol=1e-5)
    assert copy.metadata.to_dict() == model.metadata.to_dict()


def test_reds_reward_is_the_reward_of_the_subtask_reds_infers(reds_model_dir, tiny_demos):
    model = load_model(reds_model_dir)
    assert default_variant(model, 3) == "reds"
    demo = load_demos(tiny_demos, "valid", "ego", 48, limit=1, progress_bar=False)[0]
    embeddings = model.embed(demo.frames)
    played = replay(model, embeddings, 3)
    inferred = model.reds_subtasks(embeddings, model.goals(3).goals)
    per_subtask = model.reds_rewards(embeddings, model.goals(3).goals)
    assert played.subtask.tolist() == inferred.tolist() == played.completed.tolist()
    np.testing.assert_allclose(played.rewards, per_subtask[np.arange(len(demo)), inferred], atol=1e-6)
    assert np.all(played.bonus == 0.0) and np.all(played.parts.intrinsic == 0.0)
    # many environments at once: the same numbers as one episode replayed
    scorer = RewardScorer(model, 3, num_envs=2)
    parts = scorer.score(demo.frames[:2])
    assert parts.total.shape == (2,) and parts.subtask.tolist() == inferred[:2].tolist()
    # the privileged diagnostic conditions on the true subtask instead
    assert RewardScorer(model, 3, config=RewardConfig(stage_source="privileged")).stage_teller == "caller"


def test_reds_reward_quality_report(reds_model_dir, tiny_demos, tmp_path):
    out = tmp_path / "quality"
    run = subprocess.run(
        [
            Path(sys.executable).parent / "inest-reward-quality",
            reds_model_dir,
            tiny_demos,
            "--out",
            out,
            "--negative-episodes",
            "1",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "report.json").read_text())
    assert set(report["schemes"]) == {"3"} and report["schemes"]["3"]["variant"] == "reds"
    assert report["model"]["method"] == "reds"
    assert -1.0 <= report["schemes"]["3"]["spearman_progress_total_incl_bonus"]["median"] <= 1.0


def test_training_on_the_reds_reward(reds_model_dir, tmp_path, capsys):
    from inest_agent_node.train import main

    settings = small_train_config(reward="reds", model=str(reds_model_dir), subtasks=3)
    assert settings.stage_subtasks == 3
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(settings.to_dict()))
    code = main(["--config", str(tmp_path / "train.yaml"), "--out", str(tmp_path / "run"), "--reward", "reds"])
    assert code == 0, capsys.readouterr().err
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert results and (tmp_path / "run" / "learning_curve.png").exists()
    assert "reds (200 steps)" in capsys.readouterr().out


def test_a_model_of_another_method_is_one_clear_error(reds_model_dir, tmp_path, capsys):
    from inest_agent_node.train import main

    reds = load_model(reds_model_dir)
    with pytest.raises(ModelError, match="the inest reward needs a tcc model, not reds"):
        RewardScorer(reds, 3, "inest")
    with pytest.raises(ModelError, match=r"goal embeddings for \[3\] subtasks, not 1"):
        RewardScorer(reds, 1)
    # a TCC model folder (hand-built, same camera and size) under --reward reds
    encoder = EncoderConfig(image_size=48)
    goals = {"goals": np.zeros((3, encoder.embedding_dim)).tolist(), "thresholds": [0.0] * 3, "distance_scale": 1.0}
    metadata = ModelMetadata.from_dict(
        {
            "method": "tcc",
            "view": "ego",
            "encoder": encoder.to_dict(),
            "shaping": ShapingConfig().to_dict(),
            "subtasks": {"3": goals},
        }
    )
    save_model(tmp_path / "tcc", build_network("tcc", encoder), metadata)
    with pytest.raises(ModelError, match="the reds reward needs a reds model, not tcc"):
        RewardScorer(load_model(tmp_path / "tcc"), 3, "reds")
    with pytest.raises(ModelError, match="need a reds model, this one is tcc"):
        load_model(tmp_path / "tcc").reds_rewards(np.zeros((1, encoder.embedding_dim)), np.zeros((3, 32)))
    config = small_train_config(reward="reds", model=str(tmp_path / "tcc"))
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(config.to_dict()))
    code = main(["--config", str(tmp_path / "train.yaml"), "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip() == "inest-train: the reds reward needs a reds model, not tcc"
