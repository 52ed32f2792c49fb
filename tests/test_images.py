"""Raw camera buffers and JPEG or PNG files to RGB frames: the encodings a camera sends, and the
buffers the reward node must refuse."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from inest_reward_node.runtime.images import (
    ImageRejected,
    compressed_size,
    decode_compressed,
    decode_image,
    encode_compressed,
    encode_rgb,
    fit_square,
)

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


def test_a_mono8_frame_becomes_grey_rgb():
    grey = cv2.cvtColor(FRAME, cv2.COLOR_RGB2GRAY)
    data, step = encode_rgb(FRAME, "mono8")
    assert step == 7 and data == grey.tobytes()
    decoded = decode_image("mono8", 5, 7, step, data)
    assert decoded.shape == (5, 7, 3) and all((decoded[..., c] == grey).all() for c in range(3))
    data, step = encode_rgb(LARGE, "mono8")
    assert decode_image("mono8", 480, 640, step, data, size=96).shape == (96, 96, 3)


SMOOTH = cv2.GaussianBlur(LARGE, (0, 0), 6)  # a camera's image compresses; noise would not


@pytest.mark.parametrize("image_format", ["png", "jpeg", "rgb8; png compressed bgr8", "bgr8; jpeg compressed bgr8"])
def test_compressed_frames_decode_to_rgb_and_their_size_is_read_from_the_header(image_format):
    compression = "png" if "png" in image_format else "jpeg"
    data = encode_compressed(SMOOTH, compression)
    assert compressed_size(compression, np.frombuffer(data, np.uint8)) == (480, 640)
    whole, height, width = decode_compressed(image_format, data)
    assert (height, width) == (480, 640) and whole.shape == (480, 640, 3)
    if compression == "png":  # lossless
        np.testing.assert_array_equal(whole, SMOOTH)
    assert np.abs(whole.astype(int) - SMOOTH).mean() < 2  # the colours are RGB, not BGR
    fitted, _, _ = decode_compressed(image_format, data, size=96)
    # a JPEG decoded at 1/4 scale (160x120) and then fitted: what the whole frame fitted gives
    assert np.abs(fitted.astype(int) - fit_square(whole, 96)).mean() < 2


def test_a_grey_jpeg_becomes_grey_rgb():
    grey = cv2.cvtColor(SMOOTH, cv2.COLOR_RGB2GRAY)
    data = cv2.imencode(".jpg", grey)[1].tobytes()
    frame, _, _ = decode_compressed("mono8; jpeg compressed mono8", data, size=96)
    assert frame.shape == (96, 96, 3) and (frame[..., 0] == frame[..., 2]).all()


def huge_png_header() -> bytes:
    """A PNG signature and header claiming 100000x100000 pixels, and nothing else."""
    header = b"IHDR" + (100_000).to_bytes(4, "big") * 2 + bytes([8, 2, 0, 0, 0])
    return b"\x89PNG\r\n\x1a\n" + (13).to_bytes(4, "big") + header + bytes(4)


@pytest.mark.parametrize(
    ("image_format", "data", "kind", "reason"),
    [
        ("tiff", b"II*\x00", "format", "unsupported compressed format 'tiff'; expected jpeg or png"),
        ("jpeg", b"", "no_data", "no data in a jpeg image"),
        ("jpeg", b"\xff\xd8" + bytes(64), "undecodable", "a JPEG file without a frame header"),
        ("png", b"GIF89a" + bytes(40), "undecodable", "not a PNG file"),
        ("png", huge_png_header(), "too_large", "100000x100000 png image is larger than max_image_size 4096"),
        (
            "jpeg",
            encode_compressed(FRAME[:3, :3], "jpeg"),
            "too_small",
            "3x3 jpeg image is smaller than min_image_size",
        ),
    ],
)
def test_malformed_compressed_frames_are_rejected_with_the_reason_before_decoding(image_format, data, kind, reason):
    with pytest.raises(ImageRejected, match=reason) as rejected:
        decode_compressed(image_format, data, size=96, min_size=4, max_size=4096)
    assert rejected.value.kind == kind
