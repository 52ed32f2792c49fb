"""A reward method with its own model kind, added as docs/design.md ("Adding a reward method")
says: a network, its pretraining objective and its reward method, each registered in one place;
then inest-pretrain trains it, a model folder holds it and the scorer and training read it."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from inest_reward_node.learning import objectives
from inest_reward_node.learning.config import CalibrationConfig, PretrainConfig
from inest_reward_node.learning.data import Demo, load_demos
from inest_reward_node.learning.pretrain import parse_args, pretrain
from inest_reward_node.runtime import methods, model
from inest_reward_node.runtime.encoders import EncoderConfig, build_encoder
from inest_reward_node.runtime.model import ModelKind, load_model
from inest_reward_node.runtime.rewards import RewardScorer
from inest_reward_node.runtime.stage_head import StageHeadConfig

from inest_agent_node.config import TrainConfig


class ProgressNet(torch.nn.Module):
    """Frame -> predicted progress through the demonstration, in [0, 1] (a one-value embedding)."""

    def __init__(self, encoder: EncoderConfig) -> None:
        super().__init__()
        self.encoder = build_encoder(encoder)
        self.head = torch.nn.Linear(encoder.embedding_dim, 1)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        return torch.sigmoid(self.head(self.encoder(images)))


class ProgressObjective(objectives.Objective):
    """Regress each sampled frame's time, as a fraction of its demonstration."""

    def loss(self, demos: list[Demo], rng: np.random.Generator, generator: torch.Generator) -> torch.Tensor:
        picks = [(demo, int(rng.integers(len(demo.frames)))) for demo in rng.choice(demos, 16)]
        frames = np.stack([demo.frames[index] for demo, index in picks])[:, None]
        targets = np.array([index / (len(demo.frames) - 1) for demo, index in picks], dtype=np.float32)
        return torch.nn.functional.mse_loss(self.embed_clips(frames, generator)[:, 0, 0], self.tensor(targets))


class ProgressReward(methods.LearnedReward):
    """The predicted progress's gap to the goal's: 0 at the goal, negative before it."""

    name = "progress"
    model_kind = "progress"
    single_goal = True

    @staticmethod
    def subtask_rewards(model, embeddings: np.ndarray, goals) -> np.ndarray:
        return np.asarray(embeddings)[:, :1] - goals.goals[None, :, 0]

    def shaping(self, batch: methods.Batch) -> np.ndarray:
        return batch.per_subtask[:, -1].astype(np.float64)


@pytest.fixture
def progress_kind(monkeypatch):
    monkeypatch.setitem(
        model.MODEL_KINDS, "progress", ModelKind("progress", lambda encoder, _: ProgressNet(encoder), ("progress",) * 2)
    )
    monkeypatch.setitem(objectives.OBJECTIVES, "progress", ProgressObjective)
    monkeypatch.setitem(methods.REWARD_METHODS, "progress", ProgressReward)


def test_a_new_model_kind_is_pretrained_loaded_scored_and_trained_on(progress_kind, tiny_demos, tmp_path):
    config = PretrainConfig(
        dataset=str(tiny_demos),
        method="progress",
        encoder=EncoderConfig(image_size=48, embedding_dim=8),
        iterations=30,
        learning_rate=3e-3,
        validate_every=10,
        validation_batches=1,
        checkpoint_every=10,
        calibration=CalibrationConfig(
            random_episodes=2, wrong_order_episodes=0, stage_head=StageHeadConfig(iterations=0)
        ),
    )
    assert parse_args([str(tiny_demos), "--out", "o", "--method", "progress"])[0].method == "progress"
    pretrain(config, tmp_path / "run", progress_bar=False)
    loaded = load_model(tmp_path / "run" / "model")
    assert loaded.method == "progress" and isinstance(loaded.network, ProgressNet)
    assert sorted(loaded.subtasks) == [1]

    demo = load_demos(tiny_demos, "valid", loaded.view, loaded.image_size, limit=1, progress_bar=False)[0]
    scorer = RewardScorer(loaded, 1)  # the kind's default reward method
    assert scorer.variant == "progress"
    rewards = np.concatenate([scorer.score(frame[None]).shaping for frame in demo.frames])
    assert rewards.shape == (len(demo.frames),) and np.all(rewards <= 1.0)
    training = TrainConfig.from_dict({"reward": "progress", "model": str(tmp_path / "run" / "model")})
    assert training.stage_subtasks == 1
