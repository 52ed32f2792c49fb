"""Raw camera buffers to RGB frames: the encodings a camera sends, and the buffers the reward node must refuse."""

from __future__ import annotations

import numpy as np
import pytest
from inest_reward_node.images import ImageRejected, decode_image, encode_rgb

FRAME = np.random.default_rng(0).integers(0, 256, (5, 7, 3), dtype=np.uint8)


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8"])
def test_every_encoding_decodes_back_to_the_same_rgb_frame(encoding):
    data, step = encode_rgb(FRAME, encoding)
    assert step == 7 * (4 if "a" in encoding[3:] else 3)
    np.testing.assert_array_equal(decode_image(encoding, 5, 7, step, data), FRAME)


def test_bgr8_really_swaps_the_channels():
    data, _ = encode_rgb(FRAME, "bgr8")
    raw = np.frombuffer(data, np.uint8).reshape(5, 7, 3)
    np.testing.assert_array_equal(raw[..., 0], FRAME[..., 2])


def test_row_padding_in_step_is_skipped():
    data, step = encode_rgb(FRAME, "rgb8")
    padded = np.zeros((5, step + 3), np.uint8)
    padded[:, :step] = np.frombuffer(data, np.uint8).reshape(5, step)
    np.testing.assert_array_equal(decode_image("rgb8", 5, 7, step + 3, padded.tobytes()), FRAME)


@pytest.mark.parametrize(
    ("encoding", "height", "width", "step", "size", "reason"),
    [
        ("mono16", 5, 7, 14, 70, "unsupported encoding 'mono16'"),
        ("rgb8", 5, 7, 21, 0, "no pixel data"),
        ("rgb8", 0, 7, 21, 0, "empty image: 7x0"),
        ("rgb8", 5, 7, 20, 100, "step 20 is shorter than a 7-pixel rgb8 row (21 bytes)"),
        ("rgb8", 5, 7, 21, 104, "data has 104 bytes, a 7x5 image with step 21 needs 105"),
    ],
)
def test_malformed_buffers_are_rejected_with_the_reason(encoding, height, width, step, size, reason):
    with pytest.raises(ImageRejected, match=reason.replace("(", r"\(").replace(")", r"\)")):
        decode_image(encoding, height, width, step, bytes(size))
