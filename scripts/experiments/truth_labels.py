"""The labeller stand-in of the labelling-path scripts: writes the label file a person would fill
in from the contact sheets (`episode,frame,blocks`, one row per change of the blocks placed in
order), here from the simulator's truth kept in the clip file; its row count is what a person writes.

  .venv/bin/python scripts/experiments/truth_labels.py CLIPS.npz LABELS.csv
"""

from __future__ import annotations

import sys

import numpy as np


def main(clips: str, labels: str) -> None:
    with np.load(clips) as data:
        rows = ["episode,frame,blocks"]
        for episode in range(sum(key.startswith("frames_") for key in data.files)):
            progress = data[f"progress_{episode}"]
            changes = [0, *(int(i) for i in np.flatnonzero(np.diff(progress)) + 1)]
            rows += [f"{episode},{frame},{int(progress[frame])}" for frame in changes]
    with open(labels, "w") as file:
        file.write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main(*sys.argv[1:])
