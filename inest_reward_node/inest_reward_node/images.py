"""Camera frames from raw image buffers (what a `sensor_msgs/Image` carries), checked before use.

Kept free of ROS so the checks are testable alone: the reward node hands over the message's
fields and gets an RGB array or an `ImageRejected` whose message is the reason it logs and counts.
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


class ImageRejected(ValueError):
    """A frame that cannot be scored; str() is the reason."""


def decode_image(
    encoding: str, height: int, width: int, step: int, data: bytes | memoryview | np.ndarray
) -> np.ndarray:
    """(height, width, 3) uint8 RGB from a row-major buffer with `step` bytes per row (padding allowed)."""
    if encoding not in ENCODINGS:
        raise ImageRejected(f"unsupported encoding {encoding!r}; expected one of {sorted(ENCODINGS)}")
    channels, conversion, _ = ENCODINGS[encoding]
    if height <= 0 or width <= 0:
        raise ImageRejected(f"empty image: {width}x{height}")
    buffer = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data.reshape(-1)
    if buffer.size == 0:
        raise ImageRejected(f"no pixel data in a {width}x{height} {encoding} image")
    if step < width * channels:
        raise ImageRejected(f"step {step} is shorter than a {width}-pixel {encoding} row ({width * channels} bytes)")
    if buffer.size != step * height:
        raise ImageRejected(
            f"data has {buffer.size} bytes, a {width}x{height} image with step {step} needs {step * height}"
        )
    pixels = buffer.reshape(height, step)[:, : width * channels].reshape(height, width, channels)
    if conversion is None:
        return np.ascontiguousarray(pixels)
    return cv2.cvtColor(pixels, conversion)


def encode_rgb(frame: np.ndarray, encoding: str = "rgb8") -> tuple[bytes, int]:
    """(data, step) of an RGB frame in `encoding`: what a camera driver or the simulator publishes."""
    if encoding not in ENCODINGS:
        raise ValueError(f"unsupported encoding {encoding!r}; expected one of {sorted(ENCODINGS)}")
    channels, _, conversion = ENCODINGS[encoding]
    pixels = frame if conversion is None else cv2.cvtColor(frame, conversion)
    return np.ascontiguousarray(pixels).tobytes(), frame.shape[1] * channels
