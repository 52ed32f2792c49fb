"""Demonstrations from a LeRobot dataset (format v3, what lerobot 0.4 writes), read with pyarrow
and PyAV: lerobot itself is not needed.

A v3 dataset keeps per episode a row in `meta/episodes/*.parquet` saying which mp4 file of each
camera holds it and from which time (one file holds many episodes), and per frame a row in
`data/*.parquet`. Where the frames carry `subtask_index` (LeRobot's subtask annotation), each
episode's subtask ends are taken from it: a subtask ends on the last frame of its run.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .timeline import frame_at
from .videos import decode_video, resample
from .writer import RecordedEpisode, RecordingError


def read_parquet(folder: Path, columns: list[str] | None = None) -> dict[str, list[Any]]:
    files = sorted(folder.rglob("*.parquet"))
    if not files:
        raise RecordingError(f"{folder}: no parquet files")
    try:
        tables = [pq.read_table(path, columns=columns) for path in files]
    except (pa.ArrowException, OSError) as error:
        raise RecordingError(f"{folder}: unreadable parquet ({error})") from None
    return pa.concat_tables(tables, promote_options="default").to_pydict()


def read_info(root: Path) -> dict[str, Any]:
    path = root / "meta" / "info.json"
    try:
        info = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as error:
        raise RecordingError(f"{root}: not a LeRobot dataset ({path}: {error})") from None
    version = str(info.get("codebase_version", "?"))
    if not version.startswith("v3"):
        raise RecordingError(
            f"{root} is a LeRobot {version} dataset; this reads v3 "
            "(convert it with lerobot's convert_dataset_v21_to_v30)"
        )
    return info


def subtask_runs(subtasks: list[int]) -> list[int]:
    """Per run of equal subtask indices, the frame it ends on."""
    changes = np.flatnonzero(np.diff(np.asarray(subtasks)) != 0)
    return [*changes.tolist(), len(subtasks) - 1]


class LeRobotSource:
    """A v3 dataset's tables, read and checked before any video is decoded."""

    def __init__(self, root: Path, cameras: dict[str, str]) -> None:
        """`cameras`: view -> video key (e.g. "observation.images.top")."""
        self.root, self.cameras, self.info = root, cameras, read_info(root)
        features = self.info.get("features", {})
        videos = sorted(key for key, feature in features.items() if feature.get("dtype") == "video")
        for key in cameras.values():
            if key not in videos:
                raise RecordingError(f"{root}: no video feature {key!r} (it has: {', '.join(videos) or 'none'})")
        self.episodes = read_parquet(root / "meta" / "episodes")
        columns = ["episode_index", "timestamp"] + (["subtask_index"] if "subtask_index" in features else [])
        self.data = read_parquet(root / "data", columns)
        self.rows: dict[int, list[int]] = {}
        for row, episode in enumerate(self.data["episode_index"]):
            self.rows.setdefault(int(episode), []).append(row)

    def positions(self) -> list[int]:
        """The episodes table's rows in episode order."""
        return sorted(range(len(self.episodes["episode_index"])), key=lambda row: self.episodes["episode_index"][row])

    def camera_frames(self, position: int, key: str, size: int, resize: str) -> tuple[np.ndarray, np.ndarray]:
        """One camera's frames of the episode in row `position`, timed from its first."""
        row = {name: values[position] for name, values in self.episodes.items() if name.startswith(f"videos/{key}/")}
        path = self.root / self.info["video_path"].format(
            video_key=key, chunk_index=row[f"videos/{key}/chunk_index"], file_index=row[f"videos/{key}/file_index"]
        )
        start, end = float(row[f"videos/{key}/from_timestamp"]), float(row[f"videos/{key}/to_timestamp"])
        frames, times = decode_video(path, size, resize, start, end)
        return frames, times - start

    def episode(self, position: int, rate: float, size: int, resize: str) -> RecordedEpisode:
        index = int(self.episodes["episode_index"][position])
        decoded = {view: self.camera_frames(position, key, size, resize) for view, key in self.cameras.items()}
        try:
            frames, seconds = resample(decoded, rate)
        except ValueError as error:
            raise RecordingError(f"{self.root}: episode {index}: {error}") from None
        rows, ends = self.rows.get(index), None
        if "subtask_index" in self.data and rows:
            runs = subtask_runs([self.data["subtask_index"][row] for row in rows])
            ends = [frame_at(seconds, float(self.data["timestamp"][rows[end]])) for end in runs]
        return RecordedEpisode(f"episode_{index}", str(self.root), frames, seconds, ends)


def lerobot_episodes(
    root: Path, cameras: dict[str, str], rate: float, size: int, resize: str
) -> Iterator[RecordedEpisode]:
    source = LeRobotSource(root, cameras)
    return (source.episode(position, rate, size, resize) for position in source.positions())
