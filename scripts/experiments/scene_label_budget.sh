#!/usr/bin/env bash
# The two-camera reward with labels a person gives: the committed scene-camera model
# (results/long-horizon/reward-model-scene96-600demos: egocentric encoder, 800 demonstrations)
# recalibrated with no simulator-labelled episode, its 3-subtask scene-camera stage head fitted on
# the demonstrations and on WRONG wrong-order and RANDOM random-play episodes recorded through the
# scene camera and labelled through the label-file path: template and contact sheets
# (inest-label-clips), the label file (here filled from the simulator's truth by
# scripts/experiments/truth_labels.py, the person's stand-in: its row count is what a person
# writes), the labelled clip file (--stage-head-clips); with none (0 0), the demonstrations
# alone. Each step's seconds, frames and label rows go to OUT/timings.json; the model to
# OUT/model, scored on the exploit suite's development part
# (OUT/suite*.json, with and without the tracker's retraction) and by inest-reward-quality on the
# validation demonstrations and the selection set's play (OUT/quality*).
#   bash scripts/experiments/scene_label_budget.sh WRONG RANDOM [OUT]
#   (OUT default results/robot-reward-v2/scene-wrong<WRONG>-random<RANDOM>)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
WRONG=${1:?usage: scene_label_budget.sh WRONG RANDOM [OUT]}
RANDOM_EPISODES=${2:?usage: scene_label_budget.sh WRONG RANDOM [OUT]}
NAME=scene-wrong$WRONG-random$RANDOM_EPISODES
OUT=${3:-results/robot-reward-v2/$NAME}
WORK=runs/scene-labels/$NAME
SCENE_RUN=results/robot-reward/inest3-scene/seed0  # the reward settings the suite scores with
mkdir -p "$WORK" "$OUT"
# shellcheck source=scripts/experiments/timed.sh
source "$ROOT/scripts/experiments/timed.sh"  # timed NAME COMMAND..., STEPS, LOAD
record() {  # the episodes, through the scene camera, on the layouts calibration plays its own on
  "$BIN/python" - "$WORK/rollouts.npz" "$WRONG" "$RANDOM_EPISODES" <<'PY'
import sys

from inest_reward_node.learning.clips import random_play, save_clips, wrong_order_play

out, wrong, random = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
clips = wrong_order_play("allo", 96, wrong) + random_play("allo", 96, random)
save_clips(out, clips, "allo", f"{wrong} wrong-order and {random} random-play episodes, scene camera")
PY
}
CLIPS=(--stage-head-clips "$OUT/labelled.npz")
[ $((WRONG + RANDOM_EPISODES)) -gt 0 ] || CLIPS=()  # no labelled episode: the demonstrations alone
if [ ${#CLIPS[@]} -gt 0 ] && [ ! -f "$OUT/labelled.npz" ]; then
  timed record record
  timed template "$BIN/inest-label-clips" "$WORK/rollouts.npz" --template "$WORK/labels.csv" --sheets "$WORK/sheets"
  "$BIN/python" scripts/experiments/truth_labels.py "$WORK/rollouts.npz" "$WORK/labels.csv"
  timed label "$BIN/inest-label-clips" "$WORK/rollouts.npz" "$WORK/labels.csv" --out "$OUT/labelled.npz"
  cp "$WORK/labels.csv" "$OUT/labels.csv"
fi
if [ ! -f "$OUT/model/model.json" ]; then
  timed recalibrate "$BIN/inest-pretrain" runs/demos --out "$WORK/refit" \
    --recalibrate results/long-horizon/reward-model-scene96-600demos --random-episodes 0 --wrong-order-episodes 0 \
    --stage-head-view allo --stage-head-image-size 96 --stage-head-subtasks 3 "${CLIPS[@]}" --threads 1
  rm -rf "$OUT/model" && cp -r "$WORK/refit/model" "$OUT/model"
fi
[ -f "$OUT/suite.json" ] || "$BIN/inest-exploit-suite" "$OUT/model" --reward-of "$SCENE_RUN" --out "$OUT/suite.json" \
  >"$OUT/suite.txt"
[ -f "$OUT/suite-retract10.json" ] || "$BIN/inest-exploit-suite" "$OUT/model" --reward-of "$SCENE_RUN" \
  --retract-confidence 0.1 --out "$OUT/suite-retract10.json" >"$OUT/suite-retract10.txt"
[ -f "$OUT/quality/report.json" ] || "$BIN/inest-reward-quality" "$OUT/model" runs/demos --out "$OUT/quality" \
  --schemes 3 --negative-seed-offset 2000000 >"$OUT/quality.txt"
[ -f "$OUT/quality-retract10/report.json" ] || "$BIN/inest-reward-quality" "$OUT/model" runs/demos \
  --out "$OUT/quality-retract10" --schemes 3 --negative-seed-offset 2000000 --retract-confidence 0.1 \
  >"$OUT/quality-retract10.txt"
[ ${#CLIPS[@]} -eq 0 ] || [ -f "$OUT/timings.json" ] || "$BIN/python" - "$OUT" "$LOAD" "${STEPS[@]}" <<'PY'
import json
import os
import sys
from pathlib import Path

import numpy as np

out, load, *steps = sys.argv[1:]
with np.load(Path(out) / "labelled.npz") as data:
    frames = [len(data[key]) for key in data.files if key.startswith("frames_")]
rows = [line for line in (Path(out) / "labels.csv").read_text().splitlines()[1:] if line]
record = {
    "episodes": len(frames),
    "frames_on_sheets": sum(frames),
    "label_rows": len(rows),
    "label_rows_beyond_episode_starts": len(rows) - len(frames),
    "seconds": {name: round(float(value), 1) for name, value in (step.split("=") for step in steps)},
    "machine": {"cpu_cores": os.cpu_count(), "load_average_at_start": float(load)},
}
(Path(out) / "timings.json").write_text(json.dumps(record, indent=2) + "\n")
print(json.dumps(record, indent=2))
PY
