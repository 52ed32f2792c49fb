"""A person filling in inest-label-demos' label file from the contact sheets, who misreads each
subtask end by up to `--error` frames either way (uniformly), keeping the ends in order and on
the episode's frames. Reads the true ends (inest-teleop-standin --ends), writes the label file.
`labeller_standin.py TRUE_ENDS.csv DATASET OUT.csv [--error 2] [--seed 0]`
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path

import numpy as np
from inest_reward_node.recordings.label_demos import END_COLUMNS, recorded_frames
from inest_sim_node.dataset import DemoDataset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("truth", type=Path)
    parser.add_argument("dataset", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--error", type=int, default=2, help="largest misreading, frames")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    frames = recorded_frames(DemoDataset(args.dataset))
    ends: dict[str, list[int]] = defaultdict(list)
    with open(args.truth, newline="") as handle:
        for row in csv.DictReader(handle):
            ends[row["episode"]].append(int(row["frame"]))
    rng = np.random.default_rng(args.seed)
    rows, shifts = [",".join(END_COLUMNS)], []
    for name, count in frames.items():
        labelled, previous = [], -1
        for subtask, end in enumerate(ends[name]):
            later = len(ends[name]) - 1 - subtask  # frames the later ends still need
            read = int(np.clip(end + rng.integers(-args.error, args.error + 1), previous + 1, count - 1 - later))
            labelled.append(read)
            shifts.append(read - end)
            previous = read
        rows += [f"{name},{subtask},{frame}" for subtask, frame in enumerate(labelled)]
    args.out.write_text("\n".join(rows) + "\n")
    print(f"wrote {args.out}: {len(rows) - 1} rows, mean |error| {np.mean(np.abs(shifts)):.2f} frames")


if __name__ == "__main__":
    main()
