"""Camera frames from raw image buffers (what a `sensor_msgs/Image` carries), checked before use.

Kept free of ROS so the checks are testable alone: the reward node hands over the message's
fields and gets an RGB array or an `ImageRejected` naming the reason it logs and counts. The
header fields are checked against the buffer's length before any pixel is touched, so a flood
of malformed frames costs the same few microseconds per frame whatever their claimed size.
"""

from __future__ import annotations

import cv2
import numpy as np

# encoding -> (channels, OpenCV conversion to RGB, conversion from RGB); None: already RGB
ENCODINGS: dict[str, tuple[int, int | None, int | None]] = {
    "rgb8": (3, None, None),
    "bgr8": (3, cv2.COLOR_BGR2RGB, cv2.COLOR_RGB2BGR),
    "rgba8": (4, cv2.COLOR_RGBA2RGB, cv2.COLOR_RGB2RGBA),
    "bgra8": (4, cv2.COLOR_BGRA2RGB, cv2.COLOR_RGB2BGRA),
}
RESIZE_MODES = ("crop", "squash")  # crop: the centred square (the training camera's aspect); squash: all of it
MAX_IMAGE_SIZE = 1 << 15  # what decode_image accepts unless told a bound


class ImageRejected(ValueError):
    """A frame that cannot be scored: `kind` is the reason's short name (counted), str() the details."""

    def __init__(self, kind: str, detail: str) -> None:
        super().__init__(detail)
        self.kind = kind


def check_image(
    encoding: str, height: int, width: int, step: int, size: int, min_size: int = 1, max_size: int = MAX_IMAGE_SIZE
) -> int:
    """The channel count of a frame whose header fields agree with its `size` data bytes, else
    ImageRejected; `min_size` bounds the shorter side, `max_size` the longer one."""
    if encoding not in ENCODINGS:
        raise ImageRejected("encoding", f"unsupported encoding {encoding[:32]!r}; expected one of {sorted(ENCODINGS)}")
    channels = ENCODINGS[encoding][0]
    if height <= 0 or width <= 0:
        raise ImageRejected("empty", f"empty image: {width}x{height}")
    if min(height, width) < min_size:
        raise ImageRejected("too_small", f"{width}x{height} image is smaller than min_image_size {min_size}")
    if max(height, width) > max_size:
        raise ImageRejected("too_large", f"{width}x{height} image is larger than max_image_size {max_size}")
    if size == 0:
        raise ImageRejected("no_data", f"no pixel data in a {width}x{height} {encoding} image")
    if step < width * channels:
        raise ImageRejected(
            "step", f"step {step} is shorter than a {width}-pixel {encoding} row ({width * channels} bytes)"
        )
    if size != step * height:
        raise ImageRejected(
            "data_size", f"data has {size} bytes, a {width}x{height} image with step {step} needs {step * height}"
        )
    return channels


def fit_square(frame: np.ndarray, size: int, resize: str = "crop") -> np.ndarray:
    """(H, W, C) -> (size, size, C): `crop` takes the centred square first (a view), `squash` the
    whole frame; area interpolation when shrinking. A frame already (size, size) comes back as is."""
    height, width = frame.shape[:2]
    if resize == "crop" and height != width:
        side = min(height, width)
        top, left = (height - side) // 2, (width - side) // 2
        frame = frame[top : top + side, left : left + side]
    if frame.shape[:2] == (size, size):
        return frame
    interpolation = cv2.INTER_AREA if frame.shape[0] > size else cv2.INTER_LINEAR
    return cv2.resize(frame, (size, size), interpolation=interpolation)


def decode_image(
    encoding: str,
    height: int,
    width: int,
    step: int,
    data: bytes | memoryview | np.ndarray,
    size: int | None = None,
    resize: str = "crop",
    min_size: int = 1,
    max_size: int = MAX_IMAGE_SIZE,
) -> np.ndarray:
    """(height, width, 3) uint8 RGB from a row-major buffer with `step` bytes per row (padding
    allowed), or (size, size, 3) fitted by `fit_square` when `size` is given. Fitting comes before
    the colour conversion (both act per channel, so the order changes no pixel): a 640x480 bgr8
    frame is converted at 96x96, not at full size."""
    view = memoryview(data)
    channels = check_image(encoding, height, width, step, view.nbytes, min_size, max_size)
    buffer = np.frombuffer(view.cast("B"), dtype=np.uint8)  # zero-copy
    pixels = buffer.reshape(height, step)[:, : width * channels].reshape(height, width, channels)
    if size is not None:
        pixels = fit_square(pixels, size, resize)
    conversion = ENCODINGS[encoding][1]
    return np.ascontiguousarray(pixels) if conversion is None else cv2.cvtColor(pixels, conversion)


def encode_rgb(frame: np.ndarray, encoding: str = "rgb8") -> tuple[bytes, int]:
    """(data, step) of an RGB frame in `encoding`: what a camera driver or the simulator publishes."""
    if encoding not in ENCODINGS:
        raise ValueError(f"unsupported encoding {encoding!r}; expected one of {sorted(ENCODINGS)}")
    channels, _, conversion = ENCODINGS[encoding]
    pixels = frame if conversion is None else cv2.cvtColor(frame, conversion)
    return np.ascontiguousarray(pixels).tobytes(), frame.shape[1] * channels
