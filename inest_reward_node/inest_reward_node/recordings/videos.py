"""Demonstrations from video files, decoded with PyAV (FFmpeg: H.264, HEVC, AV1, VP9, ...).

A folder of videos, one file per demonstration; with two cameras, one subfolder per camera
holding a file of the same name for each demonstration (`top/demo_01.mp4`, `wrist/demo_01.mp4`).
A frame's time is its presentation time, so variable frame rates resample correctly.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import av
import numpy as np

from ..runtime.images import fit_square
from .timeline import NANOSECONDS, pick_frames
from .writer import RecordedEpisode, RecordingError

VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi", ".mov", ".webm")
SEEK_TOLERANCE = 1e-4  # seconds: LeRobot's tolerance between a frame's time and its timestamp


def decode_video(
    path: Path, size: int, resize: str, start: float = 0.0, end: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(frames (N, size, size, 3) RGB, their times in seconds) of the frames in [start, end)."""
    frames, times = [], []
    try:
        with av.open(str(path)) as container:
            stream = container.streams.video[0]
            if start > 0:
                container.seek(int(start / stream.time_base), stream=stream, backward=True)
            for frame in container.decode(stream):
                moment = float(frame.time) if frame.time is not None else len(times) / float(stream.average_rate)
                if moment < start - SEEK_TOLERANCE:
                    continue
                if end is not None and moment >= end - SEEK_TOLERANCE:
                    break
                frames.append(fit_square(frame.to_ndarray(format="rgb24"), size, resize))
                times.append(moment)
    except (av.error.FFmpegError, IndexError) as error:
        raise RecordingError(f"{path}: not a readable video ({error})") from None
    if not frames:
        raise RecordingError(f"{path}: no video frames between {start:.3f} s and {end} s")
    return np.stack(frames), np.asarray(times)


def resample(
    decoded: dict[str, tuple[np.ndarray, np.ndarray]], rate: float
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Each camera's decoded frames picked on the dataset's clock."""
    picks = pick_frames(
        {view: np.round(times * NANOSECONDS).astype(np.int64) for view, (_, times) in decoded.items()}, rate
    )
    return {view: decoded[view][0][picks.frames[view]] for view in decoded}, picks.seconds


def video_episodes(
    folder: Path, cameras: dict[str, str], rate: float, size: int, resize: str
) -> Iterator[RecordedEpisode]:
    """`cameras`: view -> subfolder ("" for videos directly in `folder`, with one camera); the
    folders are checked before the first video is decoded."""
    folders = {view: folder / sub for view, sub in cameras.items()}
    listed = {view: {p.stem: p for p in sorted(f.glob("*")) if p.suffix.lower() in VIDEO_SUFFIXES}
              for view, f in folders.items()}  # fmt: skip
    first = next(iter(cameras))
    if not listed[first]:
        raise RecordingError(f"{folders[first]}: no video files ({', '.join(VIDEO_SUFFIXES)})")
    for view, files in listed.items():
        if set(files) != set(listed[first]):
            odd = sorted(set(files) ^ set(listed[first]))
            raise RecordingError(
                f"{folders[view]} and {folders[first]} hold different demonstrations: {', '.join(odd)}"
            )

    def episode(name: str) -> RecordedEpisode:
        decoded = {view: decode_video(listed[view][name], size, resize) for view in cameras}
        try:
            frames, seconds = resample(decoded, rate)
        except ValueError as error:
            raise RecordingError(f"{listed[first][name]}: {error}") from None
        return RecordedEpisode(name, str(listed[first][name]), frames, seconds)

    return (episode(name) for name in sorted(listed[first]))
