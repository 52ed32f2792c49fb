"""Camera frames from raw image buffers (what a `sensor_msgs/Image` carries) and from JPEG or PNG
files (a `sensor_msgs/CompressedImage`, image_transport's compressed transport), checked before use.

Kept free of ROS so the checks are testable alone: the reward node hands over the message's
fields and gets an RGB array or an `ImageRejected` naming the reason it logs and counts. The
header fields are checked against the buffer's length before any pixel is touched, so a flood
of malformed frames costs the same few microseconds per frame whatever their claimed size; a
compressed frame's size is read from its JPEG or PNG header before it is decoded, and a JPEG is
decoded at the smallest of 1/8, 1/4, 1/2 or full scale that still covers the encoder's input
(libjpeg scales while it decodes: a 640x480 frame for a 96 px encoder is decoded at 160x120).
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
    "mono8": (1, cv2.COLOR_GRAY2RGB, cv2.COLOR_RGB2GRAY),
}
COMPRESSIONS = ("jpeg", "png")  # a CompressedImage's formats (image_transport: "jpeg" or "rgb8; jpeg compressed bgr8")
# OpenCV's reduced-scale reads: a JPEG decoded at 1/8, 1/4, 1/2 of its size
_REDUCED_READS = ((8, cv2.IMREAD_REDUCED_COLOR_8), (4, cv2.IMREAD_REDUCED_COLOR_4), (2, cv2.IMREAD_REDUCED_COLOR_2))
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (the ones that give the size): C0-CF but DHT (C4), JPG (C8), DAC (CC)
_JPEG_FRAME_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
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
    check_size(height, width, "image", min_size, max_size)
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


def check_size(height: int, width: int, what: str, min_size: int = 1, max_size: int = MAX_IMAGE_SIZE) -> None:
    if height <= 0 or width <= 0:
        raise ImageRejected("empty", f"empty image: {width}x{height}")
    if min(height, width) < min_size:
        raise ImageRejected("too_small", f"{width}x{height} {what} is smaller than min_image_size {min_size}")
    if max(height, width) > max_size:
        raise ImageRejected("too_large", f"{width}x{height} {what} is larger than max_image_size {max_size}")


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


def compression_of(image_format: str) -> str:
    """ "jpeg" or "png" from a CompressedImage's format: the bare name, or image_transport's
    "<encoding>; <compression> compressed <encoding>"."""
    words = image_format.replace(";", " ").lower().split()
    found = [word for word in words if word in COMPRESSIONS]
    if not found:
        raise ImageRejected("format", f"unsupported compressed format {image_format[:48]!r}; expected jpeg or png")
    return found[0]


def compressed_size(compression: str, data: np.ndarray) -> tuple[int, int]:
    """(height, width) from a JPEG's start-of-frame or a PNG's header, without decoding;
    ImageRejected if the header is not there."""
    if compression == "png":
        if data[:8].tobytes() != _PNG_SIGNATURE or data.size < 24:
            raise ImageRejected("undecodable", "not a PNG file (no PNG signature and header)")
        width, height = (int.from_bytes(data[offset : offset + 4].tobytes(), "big") for offset in (16, 20))
        return height, width
    if data[:2].tobytes() != b"\xff\xd8":
        raise ImageRejected("undecodable", "not a JPEG file (no start-of-image marker)")
    at = 2
    while at + 9 <= data.size:  # segment by segment: marker, 2-byte length, payload
        if data[at] != 0xFF:
            break
        marker, length = int(data[at + 1]), int.from_bytes(data[at + 2 : at + 4].tobytes(), "big")
        if marker in _JPEG_FRAME_MARKERS:
            return (int.from_bytes(data[at + 5 : at + 7].tobytes(), "big"),
                    int.from_bytes(data[at + 7 : at + 9].tobytes(), "big"))  # fmt: skip
        at += 2 + length
    raise ImageRejected("undecodable", "a JPEG file without a frame header")


def decode_compressed(
    image_format: str,
    data: bytes | memoryview | np.ndarray,
    size: int | None = None,
    resize: str = "crop",
    min_size: int = 1,
    max_size: int = MAX_IMAGE_SIZE,
) -> tuple[np.ndarray, int, int]:
    """(frame, height, width) of a JPEG or PNG frame: (size, size, 3) RGB fitted by `fit_square`
    when `size` is given, else the whole frame; height and width are the file's. Colour or
    grey files alike become RGB. The size is checked from the header before anything is decoded."""
    compression = compression_of(image_format)
    buffer = np.frombuffer(memoryview(data).cast("B"), dtype=np.uint8)
    if buffer.size == 0:
        raise ImageRejected("no_data", f"no data in a {compression} image")
    height, width = compressed_size(compression, buffer)
    check_size(height, width, f"{compression} image", min_size, max_size)
    read = cv2.IMREAD_COLOR
    if compression == "jpeg" and size is not None:
        short = min(height, width) if resize == "crop" else max(height, width)  # squash keeps the long side whole
        read = next((flag for factor, flag in _REDUCED_READS if short // factor >= size), cv2.IMREAD_COLOR)
    pixels = cv2.imdecode(buffer, read)
    if pixels is None:
        raise ImageRejected("undecodable", f"a {width}x{height} {compression} image that does not decode")
    if size is not None:
        pixels = fit_square(pixels, size, resize)
    return cv2.cvtColor(pixels, cv2.COLOR_BGR2RGB), height, width


def encode_compressed(frame: np.ndarray, compression: str = "jpeg", quality: int = 90) -> bytes:
    """A JPEG or PNG file of an RGB frame: what a camera's compressed topic carries."""
    if compression not in COMPRESSIONS:
        raise ValueError(f"unsupported compression {compression!r}; expected one of {COMPRESSIONS}")
    options = [cv2.IMWRITE_JPEG_QUALITY, quality] if compression == "jpeg" else []
    ok, encoded = cv2.imencode(
        f".{compression.replace('jpeg', 'jpg')}", cv2.cvtColor(frame, cv2.COLOR_RGB2BGR), options
    )
    if not ok:
        raise ValueError(f"OpenCV could not encode a {frame.shape} frame as {compression}")
    return encoded.tobytes()


def encode_rgb(frame: np.ndarray, encoding: str = "rgb8") -> tuple[bytes, int]:
    """(data, step) of an RGB frame in `encoding`: what a camera driver or the simulator publishes."""
    if encoding not in ENCODINGS:
        raise ValueError(f"unsupported encoding {encoding!r}; expected one of {sorted(ENCODINGS)}")
    channels, _, conversion = ENCODINGS[encoding]
    pixels = frame if conversion is None else cv2.cvtColor(frame, conversion)
    return np.ascontiguousarray(pixels).tobytes(), frame.shape[1] * channels
