"""Raw camera buffers to RGB frames: the encodings a camera sends, and the buffers the reward node must refuse."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from inest_reward_node.runtime.images import ImageRejected, decode_image, encode_rgb, fit_square

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
    ("encoding", "height", "width", "step", "size", "kind", "reason"),
    [
        ("mono16", 5, 7, 14, 70, "encoding", "unsupported encoding 'mono16'"),
        ("rgb8", 5, 7, 21, 0, "no_data", "no pixel data"),
        ("rgb8", 0, 7, 21, 0, "empty", "empty image: 7x0"),
        ("rgb8", 5, 7, 20, 100, "step", "step 20 is shorter than a 7-pixel rgb8 row (21 bytes)"),
        ("rgb8", 5, 7, 21, 104, "data_size", "data has 104 bytes, a 7x5 image with step 21 needs 105"),
        ("rgb8", 1, 1, 3, 3, "too_small", "1x1 image is smaller than min_image_size 4"),
        ("rgb8", 5, 9, 27, 135, "too_large", "9x5 image is larger than max_image_size 8"),
    ],
)
def test_malformed_buffers_are_rejected_with_the_reason(encoding, height, width, step, size, kind, reason):
    with pytest.raises(ImageRejected, match=reason.replace("(", r"\(").replace(")", r"\)")) as rejected:
        decode_image(encoding, height, width, step, bytes(size), min_size=4, max_size=8)
    assert rejected.value.kind == kind


def test_a_header_claiming_a_huge_image_is_refused_from_its_fields_alone():
    """100000x100000 rgb8 would be 30 GB: the bound is checked before the 27 bytes of data are looked at."""
    with pytest.raises(ImageRejected) as rejected:
        decode_image("rgb8", 100_000, 100_000, 300_000, bytes(27), max_size=4096)
    assert rejected.value.kind == "too_large"


LARGE = np.random.default_rng(1).integers(0, 256, (480, 640, 3), dtype=np.uint8)


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8"])
def test_fitting_before_the_colour_conversion_changes_no_pixel(encoding):
    data, step = encode_rgb(LARGE, encoding)
    np.testing.assert_array_equal(decode_image(encoding, 480, 640, step, data, size=96), fit_square(LARGE, 96))


def test_crop_takes_the_centred_square_and_squash_keeps_the_whole_frame():
    centre = LARGE[:, 80:560]
    data, step = encode_rgb(LARGE, "bgr8")
    cropped = decode_image("bgr8", 480, 640, step, data, size=96, resize="crop")
    np.testing.assert_array_equal(cropped, cv2.resize(centre, (96, 96), interpolation=cv2.INTER_AREA))
    squashed = decode_image("bgr8", 480, 640, step, data, size=96, resize="squash")
    np.testing.assert_array_equal(squashed, cv2.resize(LARGE, (96, 96), interpolation=cv2.INTER_AREA))
    tall = LARGE.transpose(1, 0, 2)  # 480 wide, 640 high: rows 80..560
    np.testing.assert_array_equal(fit_square(tall, 480), tall[80:560])
