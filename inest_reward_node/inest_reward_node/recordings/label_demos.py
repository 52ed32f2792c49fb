"""`inest-label-demos`: cut a dataset's demonstrations into subtasks where a person says they end.

The label file is CSV, `episode,subtask,frame`: one row per demonstration per subtask end, the
frame (from 0) on which that subtask ends: its block lies in the goal strip (with 6 subtasks,
the even ones end when the block is reached and grasped). `--template FILE` writes the rows to
fill in, with each demonstration's frame count, and `--sheets DIR` a numbered contact sheet per
demonstration to read the frames from. Every bad row (an unknown episode, a frame past the
episode's end, ends out of order, a missing or doubled end) is reported on its own line and
nothing is written; a good file is kept in the dataset's metadata.json and applied whenever the
dataset is read (inest-pretrain, inest-reward-quality).
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from inest_common.files import sha256_of, write_atomic
from inest_common.settings import OneLineParser
from inest_sim_node.dataset import SPLITS, DatasetError, DemoDataset, episode_name, write_metadata
from inest_sim_node.subtasks import DESCRIPTIONS

from ..learning.labels import write_sheets

END_COLUMNS = ("episode", "subtask", "frame")
SUBTASK_COUNTS = (3, 6)


class EndsError(ValueError):
    """A label file with bad rows: one line per problem."""

    def __init__(self, problems: list[str]) -> None:
        super().__init__("\n".join(problems))
        self.problems = problems


def recorded_frames(dataset: DemoDataset) -> dict[str, int]:
    """Each demonstration's frame count, by name, in dataset order."""
    return {episode_name(entry): int(entry["frames"]) for split in SPLITS for entry in dataset.entries(split)}


def read_ends(path: Path, frames: dict[str, int]) -> dict[str, list[int]]:
    """name -> subtask ends, checked against the demonstrations' frame counts; EndsError lists
    every bad row."""
    try:
        with open(path, newline="") as handle:
            rows = [(n, row) for n, row in enumerate(csv.reader(handle), start=1) if row and not row[0].startswith("#")]
    except (OSError, UnicodeDecodeError) as error:
        raise EndsError([f"cannot read {path}: {getattr(error, 'strerror', None) or error}"]) from None
    if rows and [cell.strip() for cell in rows[0][1]] == list(END_COLUMNS):
        rows = rows[1:]
    problems: list[str] = []
    given: dict[str, dict[int, tuple[int, int]]] = defaultdict(dict)  # name -> subtask -> (frame, line)
    for line, row in rows:
        where = f"{path.name} line {line}"
        cells = [cell.strip() for cell in row]
        if len(cells) != 3:
            problems.append(f"{where}: {row} is not episode,subtask,frame")
            continue
        name, subtask, frame = cells
        if name not in frames:
            problems.append(f"{where}: no episode {name!r} in the dataset")
            continue
        if not frame:
            problems.append(f"{where}: episode {name} subtask {subtask} has no frame yet")
            continue
        try:
            subtask_number, frame_number = int(subtask), int(frame)
        except ValueError:
            problems.append(f"{where}: subtask and frame must be integers, got {subtask!r}, {frame!r}")
            continue
        if not 0 <= subtask_number < max(SUBTASK_COUNTS):
            problems.append(f"{where}: subtask {subtask_number} is not in 0..{max(SUBTASK_COUNTS) - 1}")
        elif not 0 <= frame_number < frames[name]:
            problems.append(
                f"{where}: frame {frame_number} is past episode {name}'s end (frames 0..{frames[name] - 1})"
            )
        elif subtask_number in given[name]:
            first = given[name][subtask_number][1]
            problems.append(f"{where}: episode {name} subtask {subtask_number} is given twice (line {first})")
        else:
            given[name][subtask_number] = (frame_number, line)
    count = max((max(ends) + 1 for ends in given.values() if ends), default=0)
    if count not in SUBTASK_COUNTS:
        problems.append(f"{path.name}: the rows name {count} subtasks per demonstration; expected 3 or 6")
        raise EndsError(problems)
    for name in frames:
        ends = given.get(name, {})
        missing = [str(subtask) for subtask in range(count) if subtask not in ends]
        if missing:
            problems.append(f"{path.name}: episode {name} lacks the end of subtask {', '.join(missing)}")
            continue
        for subtask in range(1, count):
            (before, before_line), (frame, line) = ends[subtask - 1], ends[subtask]
            if frame <= before:
                problems.append(
                    f"{path.name} line {line}: episode {name} subtask {subtask} ends on frame {frame}, not after "
                    f"subtask {subtask - 1} (frame {before}, line {before_line})"
                )
    if problems:
        raise EndsError(problems)
    return {name: [given[name][subtask][0] for subtask in range(count)] for name in frames}


def apply_ends(dataset: DemoDataset, path: Path) -> dict[str, Any]:
    """Check the label file and keep it in the dataset's metadata (one atomic write)."""
    ends = read_ends(path, recorded_frames(dataset))
    record = {
        "subtasks": len(next(iter(ends.values()))),
        "labelled_by": "file",
        "file": str(path),
        "sha256": sha256_of(path),
        "labelled": datetime.now(UTC).isoformat(timespec="seconds"),
        "ends": ends,
    }
    write_metadata(dataset.root, {**dataset.metadata, "subtask_ends": record})
    return record


def write_template(path: Path, frames: dict[str, int], subtasks: int) -> None:
    lines = [
        "# episode,subtask,frame: the frame (from 0) on which this subtask of this demonstration ends",
        *(f"# subtask {index}: {text}" for index, text in enumerate(DESCRIPTIONS[subtasks])),
        f"# {len(frames)} demonstrations x {subtasks} subtask ends = {len(frames) * subtasks} rows",
        ",".join(END_COLUMNS),
    ]
    for name, count in frames.items():
        lines += [f"# {name}: {count} frames (0..{count - 1})", *(f"{name},{s}," for s in range(subtasks))]
    write_atomic(path, lambda temporary: temporary.write_text("\n".join(lines) + "\n"))


def sheet_frames(dataset: DemoDataset, view: str | None) -> tuple[list[np.ndarray], str]:
    """Every demonstration's frames through `view` (default: the scene camera where there is one,
    it shows which blocks lie in the strip)."""
    episodes = [dataset.load(split, index) for split in SPLITS for index in range(len(dataset.entries(split)))]
    chosen = view or ("allo" if "allo" in episodes[0].views else episodes[0].views[0])
    return [episode.frames(chosen) for episode in episodes], chosen


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(
        prog="inest-label-demos", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", type=Path, help="a demonstration dataset (inest-import-demos)")
    parser.add_argument("ends", type=Path, nargs="?", help="the CSV label file to apply")
    parser.add_argument("--template", type=Path, help="write the label file to fill in, and exit")
    parser.add_argument("--subtasks", type=int, choices=SUBTASK_COUNTS, default=3, help="with --template")
    parser.add_argument("--sheets", type=Path, help="with --template: a numbered contact sheet per demonstration")
    parser.add_argument("--view", choices=("ego", "allo"), help="the camera of the sheets (default: allo if there)")
    args = parser.parse_args(argv)
    if (args.template is None) == (args.ends is None):
        parser.error("give a label file to apply, or --template FILE")
    try:
        dataset = DemoDataset(args.dataset)
        frames = recorded_frames(dataset)
        if args.template is not None:
            write_template(args.template, frames, args.subtasks)
            sheets = ""
            if args.sheets is not None:
                episodes, view = sheet_frames(dataset, args.view)
                write_sheets(args.sheets, episodes, list(frames))
                sheets = f"; contact sheets ({view} camera) in {args.sheets}/"
            print(f"wrote {args.template}: {len(frames) * args.subtasks} rows to fill in{sheets}")
            return 0
        replaced = "subtask_ends" in dataset.metadata
        record = apply_ends(dataset, args.ends)
    except EndsError as error:
        for problem in error.problems:
            print(f"inest-label-demos: error: {problem}", file=sys.stderr)
        print(f"inest-label-demos: {len(error.problems)} problem(s); nothing written", file=sys.stderr)
        return 2
    except DatasetError as error:
        print(f"inest-label-demos: error: {error}", file=sys.stderr)
        return 2
    rows = len(record["ends"]) * record["subtasks"]
    again = " (replacing the subtask ends it had)" if replaced else ""
    print(f"labelled {len(record['ends'])} demonstrations of {args.dataset} from {args.ends} ({rows} rows){again}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
