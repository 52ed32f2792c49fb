"""TCC loss: zero for aligned sequences, large for shuffled ones, differentiable; training lowers it."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from inest_reward_node.learning.losses import tcc_loss

FRAMES, DIM = 16, 8


def aligned_videos(videos: int, length: float = 200.0) -> tuple[torch.Tensor, torch.Tensor]:
    """Identical trajectories along a line; the longer the line, the sharper the soft nearest neighbours."""
    positions = torch.linspace(0, 1, FRAMES)
    line = torch.zeros(FRAMES, DIM)
    line[:, 0] = positions * length
    return line.repeat(videos, 1, 1), positions.repeat(videos, 1)


def test_loss_is_near_zero_for_aligned_identical_sequences():
    embeddings, positions = aligned_videos(4)
    assert float(tcc_loss(embeddings, positions)) < 1e-4


def test_loss_is_large_for_shuffled_sequences():
    """At a realistic sharpness (soft neighbours span a few frames), shuffling each video's frames
    makes embedding neighbours temporal strangers, and independent random videos are worse still."""
    embeddings, positions = aligned_videos(4, length=20.0)
    generator = torch.Generator().manual_seed(0)
    shuffled = torch.stack([video[torch.randperm(FRAMES, generator=generator)] for video in embeddings])
    aligned_loss, shuffled_loss = float(tcc_loss(embeddings, positions)), float(tcc_loss(shuffled, positions))
    assert aligned_loss < 0.002
    assert shuffled_loss > 0.04 and shuffled_loss > 20 * aligned_loss
    unrelated = torch.randn(4, FRAMES, DIM, generator=generator) * 5.0
    assert float(tcc_loss(unrelated, positions)) > 0.1


def test_gradients_flow_to_every_embedding():
    embeddings = torch.randn(3, FRAMES, DIM, requires_grad=True)
    loss = tcc_loss(embeddings, torch.linspace(0, 1, FRAMES).repeat(3, 1))
    loss.backward()
    assert torch.isfinite(embeddings.grad).all()
    assert (embeddings.grad.abs().sum(-1) > 0).all()


def test_loss_rejects_bad_shapes():
    with pytest.raises(ValueError, match="videos >= 2"):
        tcc_loss(torch.zeros(1, FRAMES, DIM), torch.zeros(1, FRAMES))
    with pytest.raises(ValueError, match="frame_positions"):
        tcc_loss(torch.zeros(2, FRAMES, DIM), torch.zeros(2, FRAMES + 1))


def test_a_tiny_training_run_lowers_the_loss(tiny_tcc_run):
    _, run_dir = tiny_tcc_run
    state = torch.load(run_dir / "train_state.pt", weights_only=True)
    import json

    history = json.loads(state["history"])
    train = np.array([value for _, value in history["train"]])
    assert len(train) == 40
    assert train[-5:].mean() < 0.8 * train[:5].mean()
    assert (run_dir / "loss.png").stat().st_size > 1000
    assert any((run_dir / "tensorboard").iterdir())
