"""Encoders: standard ResNet-18 layout, small CNN, input conversion."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch
from inest_reward_node.runtime.encoders import EncoderConfig, ResNet18, build_encoder, frames_to_tensor, resize_frames


def test_resnet18_has_the_standard_layout():
    model = ResNet18(embedding_dim=32)
    backbone = sum(p.numel() for name, p in model.named_parameters() if not name.startswith("head"))
    assert backbone == 11_176_512  # torchvision's resnet18 without its 1000-way classifier
    with torch.no_grad():
        features = model.pool(model.stages(model.stem(torch.zeros(2, 3, 96, 96))))
    assert features.shape == (2, 512, 1, 1)


@pytest.mark.parametrize("kind", ["small_cnn", "resnet18"])
@pytest.mark.parametrize("size", [48, 96])
def test_encoders_embed_any_configured_size(kind, size):
    config = EncoderConfig(kind=kind, image_size=size, embedding_dim=16)
    model = build_encoder(config).eval()
    frames = np.random.default_rng(0).integers(0, 256, (3, size, size, 3), dtype=np.uint8)
    with torch.no_grad():
        embeddings = model(frames_to_tensor(frames))
    assert embeddings.shape == (3, 16)
    assert torch.isfinite(embeddings).all()


def test_frames_to_tensor_scales_to_unit_range_and_rejects_floats():
    frames = np.array([[[[0, 128, 255]]]], dtype=np.uint8)
    tensor = frames_to_tensor(frames)
    assert tensor.shape == (1, 3, 1, 1)
    assert tensor.flatten().tolist() == pytest.approx([-1.0, 128 * 2 / 255 - 1, 1.0], abs=1e-6)
    with pytest.raises(ValueError, match="uint8"):
        frames_to_tensor(frames.astype(np.float32))


def test_resize_frames_to_the_encoder_input():
    frames = np.zeros((2, 64, 80, 3), np.uint8)
    assert resize_frames(frames, 48).shape == (2, 48, 48, 3)
    with pytest.raises(ValueError, match=r"\(N, H, W, 3\)"):
        resize_frames(np.zeros((64, 64, 3), np.uint8), 48)


def test_square_frames_resize_exactly_as_before_the_crop_policy():
    """Training reads the simulator's square frames through resize_frames: cropping must not change a bit."""
    frames = np.random.default_rng(2).integers(0, 256, (3, 128, 128, 3), dtype=np.uint8)
    for size, interpolation in ((96, cv2.INTER_AREA), (160, cv2.INTER_LINEAR)):
        expected = np.stack([cv2.resize(frame, (size, size), interpolation=interpolation) for frame in frames])
        np.testing.assert_array_equal(resize_frames(frames, size), expected)
    assert resize_frames(frames, 128) is frames


def test_small_cnn_widths_set_its_convolutions():
    config = EncoderConfig(image_size=48, widths=[8, 16, 16])  # as read back from JSON
    assert config.widths == (8, 16, 16) and config.to_dict()["widths"] == (8, 16, 16)
    model = build_encoder(config).eval()
    convolutions = [module for module in model.modules() if isinstance(module, torch.nn.Conv2d)]
    assert [conv.out_channels for conv in convolutions] == [8, 16, 16]
    with torch.no_grad():
        assert model(frames_to_tensor(np.zeros((2, 48, 48, 3), np.uint8))).shape == (2, 32)


def test_encoder_config_rejects_bad_values():
    with pytest.raises(ValueError, match="unknown encoder kind"):
        EncoderConfig(kind="vgg")
    with pytest.raises(ValueError, match="image_size"):
        EncoderConfig(image_size=8)
    with pytest.raises(ValueError, match="widths"):
        EncoderConfig(widths=(32, 0))
