"""Recorded demonstrations written as a demonstration dataset (format 2, `inest_sim_node.dataset`).

The dataset is written into `<out>.partial` and renamed to `out` once complete, so an interrupted
import leaves no folder that looks finished; an existing `out` is never touched.
"""

from __future__ import annotations

import platform
import shutil
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib.metadata import version
from pathlib import Path
from typing import Any

import numpy as np
from inest_sim_node.dataset import FORMAT, FORMAT_VERSION, DatasetError, Episode, write_episode, write_metadata
from inest_sim_node.subtasks import DESCRIPTIONS, SCHEMES, labels_from_ends


class RecordingError(ValueError):
    """A recording that cannot be imported; the message names the file and what is wrong."""


@dataclass
class RecordedEpisode:
    """One demonstration from a recording, already on the dataset's clock and image size."""

    name: str  # what the label file calls it
    source: str  # the file it came from
    frames: dict[str, np.ndarray]  # view ("ego", "allo") -> (N, S, S, 3) uint8
    seconds: np.ndarray  # (N,) float64 from its first frame
    subtask_ends: list[int] | None = None  # frames its subtasks end on, where the recording says


def usable_ends(ends: list[int], length: int) -> bool:
    """Whether a recording's own subtask ends cut it (3 or 6 ends, rising on distinct frames; two
    subtasks that end within one frame of the dataset's clock cannot be told apart)."""
    try:
        labels_from_ends(ends, length)
    except ValueError:
        return False
    return True


def partial_folder(out: Path) -> Path:
    return out.with_name(out.name + ".partial")


def check_out(out: Path) -> None:
    if out.exists():
        raise DatasetError(f"{out} exists; choose another --out folder (an import never writes into one)")


def write_recorded_dataset(
    out: Path, episodes: Iterable[RecordedEpisode], record: dict[str, Any], valid_fraction: float
) -> dict[str, Any]:
    """Write every episode, then metadata.json; `record` is the import's configuration.
    The first episodes, in the order given, form the train split, the last `valid_fraction` of
    them the validation split, as inest-collect-demos splits."""
    check_out(out)
    partial = partial_folder(out)
    shutil.rmtree(partial, ignore_errors=True)  # what an interrupted import left
    (partial / "episodes").mkdir(parents=True)
    try:
        metadata = write_episodes(partial, episodes, record, valid_fraction)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    partial.rename(out)
    return metadata


def write_episodes(
    partial: Path, episodes: Iterable[RecordedEpisode], record: dict[str, Any], valid_fraction: float
) -> dict[str, Any]:
    entries, names, ends = [], set(), {}
    for index, recorded in enumerate(episodes):
        if recorded.name in names:
            raise DatasetError(f"two episodes are named {recorded.name!r}; names must be unique")
        names.add(recorded.name)
        episode = Episode(
            seed=index, ego=recorded.frames.get("ego"), allo=recorded.frames.get("allo"), timestamps=recorded.seconds
        )
        relative = f"episodes/episode_{index:06d}.npz"
        entries.append(
            {
                "file": relative,
                "name": recorded.name,
                "seed": index,
                "frames": len(episode),
                "seconds": round(float(recorded.seconds[-1]), 3),
                "source": recorded.source,
                "sha256": write_episode(partial / relative, episode),
                "content_sha256": episode.content_sha256(),
            }
        )
        if recorded.subtask_ends is not None and usable_ends(recorded.subtask_ends, len(episode)):
            ends[recorded.name] = recorded.subtask_ends
    if len(entries) < 2:
        raise DatasetError(f"the recordings hold {len(entries)} episode(s); a dataset needs at least 2")
    train = len(entries) - round(len(entries) * valid_fraction)
    metadata: dict[str, Any] = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "config": record,
        "versions": {
            "python": platform.python_version(),
            **{library: version(library) for library in ("numpy", "rosbags", "pyarrow", "av")},
        },
        "label_schemes": {str(s): list(DESCRIPTIONS[s]) for s in SCHEMES},
        "episodes": {"train": entries[:train], "valid": entries[train:]},
        "complete": True,
    }
    if ends and len(ends) == len(entries):
        metadata["subtask_ends"] = {
            "subtasks": len(next(iter(ends.values()))),
            "labelled_by": record["source"]["kind"],
            "ends": ends,
        }
    write_metadata(partial, metadata)
    return metadata
