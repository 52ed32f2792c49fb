#!/usr/bin/env bash
# How long each step of a robot user's labelling path takes, at the 10-episode label budget of
# results/robot-reward/label-budget: record 10 episodes (here in the simulator: `negatives`, the
# budget's 5 random-play and 5 wrong-order episodes, or RUN, a checkpointed inest-train run's own
# rollouts through inest-record-clips; on a robot, the camera's MCAP), write the label template
# and contact sheets, fill in the label file (here from the simulator's truth, a stand-in for the
# person: its row count is what a person writes), turn it into labelled clips, recalibrate the
# committed egocentric encoder on the demonstrations and those clips alone, and check the result
# with inest-reward-quality (its report: false completions and misses). Each step's wall-clock
# seconds, the frames shown and the label rows written go to
# results/robot-reward/labelling-path/<negatives|policy>/timings.json, beside the check's report.
# The labelled episodes raise the completion thresholds as the simulator's random play does
# (--clips-raise-thresholds); RAISE_THRESHOLDS=0 fits the stage classifier on them only
# (the folder's name then ends in -classifier-only).
#   [RAISE_THRESHOLDS=0] bash scripts/experiments/labelling_path_timing.sh negatives|RUN
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
SOURCE=${1:?usage: labelling_path_timing.sh negatives|RUN (a checkpointed inest-train run folder)}
NAME=$([ "$SOURCE" = negatives ] && echo negatives || echo policy)
RAISE=(--clips-raise-thresholds)
if [ "${RAISE_THRESHOLDS:-1}" = 0 ]; then RAISE=() && NAME=$NAME-classifier-only; fi
WORK=runs/labelling-path/$NAME
OUT=results/robot-reward/labelling-path/$NAME
rm -rf "$WORK" && mkdir -p "$WORK" "$OUT"
# the budget's labelled episodes are committed beside their results (the agent check's model reads them)
LABELLED=$([ "$NAME" = negatives ] && echo "$OUT/labelled.npz" || echo "$WORK/labelled.npz")
# shellcheck source=scripts/experiments/timed.sh
source "$ROOT/scripts/experiments/timed.sh"  # timed NAME COMMAND..., STEPS, LOAD

record_negatives() {  # the budget's episodes, on the layouts calibration plays them on
  "$BIN/python" -c '
import sys

from inest_reward_node.learning.clips import random_play, save_clips, wrong_order_play

clips = random_play("ego", 96, 5) + wrong_order_play("ego", 96, 5)
save_clips(sys.argv[1], clips, "ego", "5 random-play and 5 wrong-order episodes")
' "$WORK/rollouts.npz"
}

if [ "$SOURCE" = negatives ]; then
  timed record record_negatives
else
  timed record "$BIN/inest-record-clips" "$SOURCE" --episodes 10 --out "$WORK/rollouts.npz"
fi
timed template "$BIN/inest-label-clips" "$WORK/rollouts.npz" --template "$WORK/labels.csv" --sheets "$WORK/sheets"
# the person's step, done here from the simulator's truth: one row per change of the blocks placed
"$BIN/python" scripts/experiments/truth_labels.py "$WORK/rollouts.npz" "$WORK/labels.csv"
timed label "$BIN/inest-label-clips" "$WORK/rollouts.npz" "$WORK/labels.csv" --out "$LABELLED"
timed recalibrate "$BIN/inest-pretrain" runs/demos --out "$WORK/refit" --recalibrate results/long-horizon/reward-model \
  --random-episodes 0 --wrong-order-episodes 0 --clips "$LABELLED" "${RAISE[@]}" \
  --stage-head-iterations 0 --threads 1
timed check "$BIN/inest-reward-quality" "$WORK/refit/model" runs/demos --out "$WORK/quality" --schemes 3 \
  --stage-evidence embedding --stage-filter forward
cp "$WORK/quality/report.json" "$WORK/check.log" "$OUT/"

"$BIN/python" - "$WORK" "$OUT/timings.json" "$SOURCE" "${#RAISE[@]}" "$LOAD" "${STEPS[@]}" <<'EOF'
import json
import os
import sys
from pathlib import Path

import numpy as np

work, out, source, raising, load, *steps = sys.argv[1:]
with np.load(Path(work) / "rollouts.npz") as data:
    frames = [len(data[key]) for key in data.files if key.startswith("frames_")]
rows = [line for line in (Path(work) / "labels.csv").read_text().splitlines()[1:] if line]
record = {
    "episodes_from": source,
    "clips_raise_thresholds": raising == "1",
    "episodes": len(frames),
    "frames_on_sheets": sum(frames),
    "label_rows": len(rows),
    "label_rows_beyond_episode_starts": len(rows) - len(frames),
    "seconds": {name: round(float(value), 1) for name, value in (step.split("=") for step in steps)},
    "machine": {"cpu_cores": os.cpu_count(), "load_average_at_start": float(load)},
}
Path(out).write_text(json.dumps(record, indent=2) + "\n")
print(json.dumps(record, indent=2))
EOF
