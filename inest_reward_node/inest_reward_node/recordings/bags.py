"""Demonstrations from ROS 2 bags, read with `rosbags` (no ROS install): rosbag2 folders or single
.mcap / .db3 files, `sensor_msgs/Image` or `sensor_msgs/CompressedImage` camera topics.

One bag per demonstration, or one bag cut into episodes by a CSV file of `episode,start,end`
rows: seconds since the bag's first message (what players show), or, from 1e9 on, seconds since
the epoch on the recorder's clock (what a teleoperation tool logs beside the bag). Frames are
placed in time by their header stamps (by the bag's receive times with `stamps="receive"`, or
where a camera leaves its stamps zero). A bag is read twice: once for the stamps, once to
decode only the frames the dataset's clock picks.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from ..runtime.images import ImageRejected, decode_compressed, decode_image
from .timeline import NANOSECONDS, pick_frames
from .writer import RecordedEpisode, RecordingError

IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
STAMP_SOURCES = ("header", "receive")
EPOCH_SECONDS = 1e9  # times from here on are since the epoch (2001-09-09), not since the bag's start


def message_frame(message: object, size: int, resize: str) -> np.ndarray:
    """An Image or CompressedImage message as a (size, size, 3) RGB frame."""
    if hasattr(message, "format"):
        return decode_compressed(message.format, message.data, size, resize)[0]
    return decode_image(message.encoding, message.height, message.width, message.step, message.data, size, resize)


def read_episode_times(path: Path) -> list[tuple[str, float, float]]:
    """(name, start, end) per row of an episode-times file; RecordingError names a bad row."""
    try:
        with open(path, newline="") as handle:
            rows = [row for row in csv.reader(handle) if row and not row[0].lstrip().startswith("#")]
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror}") from None
    if rows and [cell.strip() for cell in rows[0]] == ["episode", "start", "end"]:
        rows = rows[1:]
    episodes = []
    for number, row in enumerate(rows, start=1):
        try:
            name, start, end = row[0].strip(), float(row[1]), float(row[2])
            if len(row) != 3 or not name:
                raise ValueError
        except (ValueError, IndexError):
            raise RecordingError(f"{path}: row {number} {row} is not episode,start,end (seconds)") from None
        if not 0 <= start < end:
            raise RecordingError(f"{path}: row {number}: episode {name!r} needs 0 <= start < end, got {start}, {end}")
        episodes.append((name, start, end))
    if not episodes:
        raise RecordingError(f"{path}: no episodes")
    return episodes


class Bag:
    """One rosbag2 recording and the camera topics to take from it."""

    def __init__(self, path: Path, cameras: dict[str, str], stamps: str = "header") -> None:
        self.path, self.cameras, self.stamps = path, cameras, stamps
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        try:
            with Reader(path) as reader:
                self.start = reader.start_time
                topics = {connection.topic: connection.msgtype for connection in reader.connections}
        except Exception as error:  # rosbags raises its own errors per storage plugin
            raise RecordingError(f"{path}: not a readable ROS 2 bag ({error})") from None
        self.image_topics = sorted(topic for topic, kind in topics.items() if kind in IMAGE_TYPES)
        for topic in cameras.values():
            if topics.get(topic) not in IMAGE_TYPES:
                found = ", ".join(self.image_topics) or "none"
                raise RecordingError(f"{path}: no Image or CompressedImage topic {topic!r} (image topics: {found})")

    def receive_time(self, seconds: float) -> int:
        """A times file's moment on the bag's receive clock (nanoseconds since the epoch)."""
        return round(seconds * NANOSECONDS) + (0 if seconds >= EPOCH_SECONDS else self.start)

    def _messages(self, start: int | None = None, stop: int | None = None) -> Iterator[tuple[str, int, object]]:
        """(camera, receive time, message) in the bag's order, within [start, stop) receive times."""
        by_topic = {topic: view for view, topic in self.cameras.items()}
        with Reader(self.path) as reader:
            wanted = [connection for connection in reader.connections if connection.topic in by_topic]
            for connection, received, raw in reader.messages(wanted, start=start, stop=stop):
                yield by_topic[connection.topic], received, self.typestore.deserialize_cdr(raw, connection.msgtype)

    def episode(
        self, name: str, rate: float, size: int, resize: str, span: tuple[float, float] | None
    ) -> RecordedEpisode:
        start, stop = (None, None) if span is None else (self.receive_time(span[0]), self.receive_time(span[1]))
        stamps: dict[str, list[int]] = {view: [] for view in self.cameras}
        for view, received, message in self._messages(start, stop):
            stamp = message.header.stamp.sec * NANOSECONDS + message.header.stamp.nanosec
            stamps[view].append(received if self.stamps == "receive" or stamp == 0 else stamp)
        try:
            picks = pick_frames({view: np.asarray(times) for view, times in stamps.items()}, rate)
        except ValueError as error:
            raise RecordingError(f"{self.path}: episode {name!r}: {error}") from None
        wanted = {view: {} for view in self.cameras}  # view -> input index -> output frames
        for view, indices in picks.frames.items():
            for output, index in enumerate(indices):
                wanted[view].setdefault(int(index), []).append(output)
        frames = {view: np.zeros((len(picks.seconds), size, size, 3), np.uint8) for view in self.cameras}
        counts = dict.fromkeys(self.cameras, 0)
        for view, _, message in self._messages(start, stop):
            index, counts[view] = counts[view], counts[view] + 1
            if index in wanted[view]:
                try:
                    frames[view][wanted[view][index]] = message_frame(message, size, resize)
                except ImageRejected as error:
                    raise RecordingError(f"{self.path}: {self.cameras[view]} frame {index}: {error}") from None
        return RecordedEpisode(name, str(self.path), frames, picks.seconds)


def bag_episodes(
    paths: list[Path],
    cameras: dict[str, str],
    rate: float,
    size: int,
    resize: str,
    episode_times: Path | None = None,
    stamps: str = "header",
) -> Iterator[RecordedEpisode]:
    """Each bag a demonstration, or the one bag cut at `episode_times`; every bag and the times
    file are checked before the first episode is read."""
    if episode_times is not None and len(paths) != 1:
        raise RecordingError(f"--episode-times cuts one bag into episodes; {len(paths)} bags were given")
    opened = [Bag(path, cameras, stamps) for path in paths]
    if episode_times is not None:
        spans = read_episode_times(episode_times)
        return (opened[0].episode(name, rate, size, resize, (start, end)) for name, start, end in spans)
    names = [path.name if path.is_dir() else path.stem for path in paths]
    return (bag.episode(name, rate, size, resize, None) for bag, name in zip(opened, names, strict=True))
