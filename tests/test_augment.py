"""Augmentation keeps the colour signal the task depends on and is consistent within a video."""

from __future__ import annotations

import cv2
import numpy as np
import torch
from inest_reward_node.learning.data import AugmentConfig, augment_videos, stratified_indices
from inest_reward_node.runtime.encoders import frames_to_tensor
from inest_sim_node.render import PALETTE

BLOCKS = ("red", "blue", "yellow")


def palette_frame() -> np.ndarray:
    """Three block-coloured squares on the floor colour, away from the borders a shift replicates."""
    frame = np.full((48, 48, 3), PALETTE["floor"], np.uint8)
    for i, name in enumerate(BLOCKS):
        frame[18:30, 4 + 14 * i : 16 + 14 * i] = PALETTE[name]
    return frame


def hue_degrees(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb.reshape(-1, 1, 3), cv2.COLOR_RGB2HSV_FULL)[:, 0, 0].astype(float) * 360 / 256


def to_uint8(tensor: torch.Tensor) -> np.ndarray:
    return ((tensor.permute(0, 2, 3, 1).numpy() + 1) * 127.5).round().clip(0, 255).astype(np.uint8)


def test_block_colours_keep_their_hue_and_stay_distinguishable():
    clip = frames_to_tensor(np.repeat(palette_frame()[None], 64, axis=0), channels_last=False)
    augmented = augment_videos(
        clip.view(64, 1, 3, 48, 48), AugmentConfig(max_shift=0), torch.Generator().manual_seed(0)
    )
    references = hue_degrees(np.array([PALETTE[name] for name in BLOCKS], np.uint8))
    for frame in to_uint8(augmented.flatten(0, 1)):
        centres = np.array([frame[24, 10 + 14 * i] for i in range(3)])
        hues = hue_degrees(centres)
        difference = np.abs((hues - references + 180) % 360 - 180)
        # hue moves only where brightening clips a channel (yellow's red, by up to ~9 degrees)
        assert difference.max() < 12.0, (hues, references)
        # and every block is still nearest its own colour, not another block's or the goal strip's
        candidates = np.append(references, hue_degrees(np.array([PALETTE["goal"]], np.uint8)))
        nearest = [int(np.argmin(np.abs((hue - candidates + 180) % 360 - 180))) for hue in hues]
        assert nearest == [0, 1, 2]


def test_augmentation_is_the_same_for_every_frame_of_a_video():
    clip = frames_to_tensor(np.repeat(palette_frame()[None], 6, axis=0), channels_last=False).view(2, 3, 3, 48, 48)
    augmented = augment_videos(clip, AugmentConfig(), torch.Generator().manual_seed(3))
    assert augmented.shape == clip.shape
    for video in augmented:
        assert torch.equal(video[0], video[1]) and torch.equal(video[0], video[2])
    assert not torch.equal(augmented[0], augmented[1])  # but videos differ
    assert torch.equal(augment_videos(clip, AugmentConfig(enabled=False), torch.Generator()), clip)


def test_stratified_indices_are_sorted_and_cover_the_video():
    rng = np.random.default_rng(0)
    for length, count in ((80, 32), (10, 32), (32, 32)):
        indices = stratified_indices(length, count, rng)
        assert len(indices) == count
        assert np.all(np.diff(indices) >= 0)
        assert indices.min() >= 0 and indices.max() < length
    indices = stratified_indices(100, 10, rng)
    assert np.all(indices // 10 == np.arange(10))  # one per tenth
