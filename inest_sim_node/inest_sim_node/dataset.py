"""Demonstration datasets: one compressed .npz per episode plus `metadata.json`.

Layout of a dataset folder:
    metadata.json            config, versions, label schemes, and per split the list of
                             episodes with seed, frame count, sha256 of the file and
                             sha256 of its arrays (`content_sha256`)
    episodes/seed_000042.npz  one episode (see `Episode` for the arrays inside)

Version 2 holds a robot's recordings too (`inest-import-demos`): their episodes have one or two
cameras and none of the simulator's arrays, and their subtask ends come from a person's label
file (`inest-label-demos`), kept in `metadata.json` (`subtask_ends`) and applied on reading.

Files are written atomically (temporary name, then rename), so an interrupted collection
never leaves a half-written episode behind, and every read checks the recorded sha256 so
a corrupt or truncated file is reported by name instead of feeding garbage to training.
The file hashes change with every collection (the archive stores write times); the content
hashes, and `DemoDataset.content_hash` over them, name the same demonstrations identically
wherever and whenever they were collected, which is what a model records as its dataset.
(The file helpers themselves, which the reward model and the trainer use too, are in
`inest_common.files`.)
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from inest_common.files import read_versioned_json, sha256_of, write_atomic

from .subtasks import SCHEMES, labels_from_ends

METADATA_FILE = "metadata.json"
FORMAT = "inest-demonstrations"
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)  # 1: simulator datasets before recordings could be imported
SPLITS = ("train", "valid")
VIEWS = ("ego", "allo")


class DatasetError(RuntimeError):
    """A dataset file is missing, corrupt, or does not match its metadata."""


OPTIONAL_ARRAYS = ("ego", "allo", "actions", "states", "rewards", "progress", "text", "timestamps")


@dataclass
class Episode:
    """One demonstration. Frames: T + 1 (the reset frame, then one per action); actions: T.

    A simulator episode has every array; a recorded one (`inest-import-demos`) has one or two
    cameras and `timestamps`, and its progress and labels once its subtask ends are labelled."""

    seed: int  # the layout seed; a recorded episode's number in its dataset
    ego: np.ndarray | None  # (T+1, S, S, 3) uint8, egocentric camera
    allo: np.ndarray | None  # (T+1, S, S, 3) uint8, allocentric camera
    actions: np.ndarray | None = None  # (T, 3) float32: speed, turn, grip in [-1, 1]
    states: np.ndarray | None = None  # (T+1, D) float32, entries named by env.STATE_FIELDS
    rewards: np.ndarray | None = None  # (T,) float32, the environment's dense oracle reward
    progress: np.ndarray | None = None  # (T+1,) int8, correctly ordered blocks in the goal
    labels: dict[int, np.ndarray] = field(default_factory=dict)  # scheme -> (T+1,) int8 label per frame
    ends: dict[int, np.ndarray] = field(default_factory=dict)  # scheme -> (scheme,) int32 frame each subtask ends on
    text: np.ndarray | None = None  # (T+1,) str, the thesis's 3-subtask description of each frame
    timestamps: np.ndarray | None = None  # (T+1,) float64 seconds since the first frame, recorded episodes

    def __len__(self) -> int:
        return len(self.ego if self.ego is not None else self.allo)

    @property
    def views(self) -> tuple[str, ...]:
        return tuple(view for view in VIEWS if getattr(self, view) is not None)

    def frames(self, view: str) -> np.ndarray:
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; expected 'ego' or 'allo'")
        frames = getattr(self, view)
        if frames is None:
            raise DatasetError(f"the demonstrations have no {view!r} camera (they hold {', '.join(self.views)})")
        return frames

    def with_subtask_ends(self, ends: list[int]) -> Episode:
        """The episode cut into subtasks at `ends` (3 or 6 frames, see `labels_from_ends`)."""
        progress, labels, scheme_ends = labels_from_ends(ends, len(self))
        return replace(self, progress=progress, labels=labels, ends=scheme_ends)

    def to_arrays(self) -> dict[str, np.ndarray]:
        arrays = {"seed": np.int64(self.seed)}
        arrays.update({name: getattr(self, name) for name in OPTIONAL_ARRAYS if getattr(self, name) is not None})
        for scheme in self.labels:
            arrays[f"labels_{scheme}"] = self.labels[scheme]
            arrays[f"ends_{scheme}"] = self.ends[scheme]
        return arrays

    def content_sha256(self) -> str:
        """sha256 of every array's name, dtype, shape and bytes: the episode, not its file."""
        digest = hashlib.sha256()
        for name, array in sorted(self.to_arrays().items()):
            array = np.ascontiguousarray(array)
            digest.update(f"{name}:{array.dtype.str}:{array.shape}\n".encode())
            digest.update(array.tobytes())
        return digest.hexdigest()

    @classmethod
    def from_arrays(cls, arrays: Any) -> Episode:
        present = [s for s in SCHEMES if f"labels_{s}" in arrays]
        return cls(
            seed=int(arrays["seed"]),
            **{name: arrays.get(name) for name in OPTIONAL_ARRAYS},
            labels={s: arrays[f"labels_{s}"] for s in present},
            ends={s: arrays[f"ends_{s}"] for s in present},
        )


def write_episode(path: Path, episode: Episode) -> str:
    """Write one episode file; returns its sha256 for the metadata."""

    def save(temporary: Path) -> None:
        with open(temporary, "wb") as handle:
            np.savez_compressed(handle, **episode.to_arrays())

    write_atomic(path, save)
    return sha256_of(path)


def check_episode_file(path: Path, sha256: str) -> None:
    if not path.is_file():
        raise DatasetError(f"missing episode file {path}")
    if sha256_of(path) != sha256:
        raise DatasetError(f"corrupt episode file {path}: its sha256 does not match metadata.json")


def read_episode(path: Path, sha256: str | None = None) -> Episode:
    """Load one episode, checking it against the recorded sha256 when given."""
    if sha256 is not None:
        check_episode_file(path, sha256)
    elif not path.is_file():
        raise DatasetError(f"missing episode file {path}")
    try:
        with np.load(path, allow_pickle=False) as arrays:
            return Episode.from_arrays({key: arrays[key] for key in arrays.files})
    except (zipfile.BadZipFile, ValueError, KeyError, OSError, EOFError) as error:
        raise DatasetError(f"corrupt episode file {path}: {error}") from error


def write_metadata(root: Path, metadata: dict[str, Any]) -> None:
    def save(temporary: Path) -> None:
        temporary.write_text(json.dumps(metadata, indent=2, sort_keys=True) + "\n")

    write_atomic(root / METADATA_FILE, save)


def read_metadata(root: Path) -> dict[str, Any]:
    return read_versioned_json(root / METADATA_FILE, FORMAT, READABLE_VERSIONS, "dataset", DatasetError)


def episode_name(entry: dict[str, Any]) -> str:
    """What a label file calls an episode: a recording's name, or a simulator episode's file stem."""
    return entry.get("name") or Path(entry["file"]).stem


class DemoDataset:
    """Read access to a finished dataset: `dataset.load("train", 3)` or iterate a split."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.metadata = read_metadata(self.root)
        if not self.metadata.get("complete", False):
            raise DatasetError(f"dataset at {self.root} is incomplete; finish it by running the collector again")

    def entries(self, split: str) -> list[dict[str, Any]]:
        if split not in SPLITS:
            raise ValueError(f"unknown split {split!r}; expected one of {SPLITS}")
        return self.metadata["episodes"][split]

    def __len__(self) -> int:
        return sum(len(self.entries(split)) for split in SPLITS)

    def load(self, split: str, index: int) -> Episode:
        entries = self.entries(split)
        if not 0 <= index < len(entries):
            raise IndexError(f"{split} split has {len(entries)} episodes, no index {index}")
        entry = entries[index]
        episode = read_episode(self.root / entry["file"], entry["sha256"])
        labelled = self.metadata.get("subtask_ends")
        return episode.with_subtask_ends(labelled["ends"][episode_name(entry)]) if labelled else episode

    def require_subtask_ends(self) -> None:
        """Refuse recorded demonstrations nobody has cut into subtasks yet (a simulator's are cut)."""
        if "subtask_ends" not in self.metadata and "collect" not in self.metadata["config"]:
            raise DatasetError(
                f"the demonstrations in {self.root} have no subtask ends: label them with inest-label-demos"
            )

    def segmented_by(self) -> str:
        """Who cut the demonstrations into subtasks: what a model fitted on them records."""
        labelled = self.metadata.get("subtask_ends")
        if labelled is None:
            return "dataset (the simulator's subtask ends)"
        if labelled["labelled_by"] == "file":
            rows = len(labelled["ends"]) * labelled["subtasks"]
            return f"label file {Path(labelled['file']).name} ({rows} rows, sha256 {labelled['sha256'][:12]})"
        return f"the recording's own subtask annotation ({labelled['labelled_by']})"

    def names(self) -> list[str]:
        return [episode_name(entry) for split in SPLITS for entry in self.entries(split)]

    def content_hash(self) -> str:
        """sha256 over every split's episodes (seed and content hash), the same for the same
        demonstrations on any machine. A dataset collected before content hashes were recorded
        has its episodes read to compute them."""
        digest = hashlib.sha256()
        for split in SPLITS:
            for index, entry in enumerate(self.entries(split)):
                content = entry.get("content_sha256") or self.load(split, index).content_sha256()
                digest.update(f"{split}:{entry['seed']}:{content}\n".encode())
        if "subtask_ends" in self.metadata:  # labelled by a person's file: the labels are part of the data
            digest.update(json.dumps(self.metadata["subtask_ends"]["ends"], sort_keys=True).encode())
        return digest.hexdigest()

    def verify(self) -> None:
        """Check every file against metadata.json; raises DatasetError naming the first bad one."""
        for split in SPLITS:
            for entry in self.entries(split):
                check_episode_file(self.root / entry["file"], entry["sha256"])
