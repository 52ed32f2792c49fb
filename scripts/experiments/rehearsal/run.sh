#!/usr/bin/env bash
# The robot path rehearsed with the simulator as the robot, against the simulator-native pipeline
# at the same number of demonstrations. Robot arm: record a session of N takes over the graph
# (record_session.sh: compressed cameras, inest-record, the teleoperation stand-in), import it,
# write the label template and contact sheets, a labeller stand-in fills the ends in, off by up to
# +-2 frames (labeller_standin.py), label, pretrain. Native arm: inest-collect-demos N (the
# simulator's exact ends), pretrain with the same recipe. Both models are judged by
# inest-reward-quality on the same 20 held-out simulator demonstrations (seeds from 5000, their
# true ends) and the same random and wrong-order play, 3 pretraining seeds per arm
# (INEST_REHEARSAL_SEEDS); the robot model is then served over the graph with JPEG cameras for a
# short training run (serve/). Each step's seconds go to steps.tsv.
#   bash scripts/experiments/rehearsal/run.sh [OUT] [N]   # OUT default results/rehearsal, N 50
# Work files (bag, datasets, runs) go to runs/rehearsal; about 15 minutes per pretraining on 2 cores.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
cd "$ROOT"
OUT=${1:-results/rehearsal}
N=${2:-50}
WORK=${INEST_REHEARSAL_WORK:-runs/rehearsal}
BIN=.venv/bin
# the recipe both arms share: the default TCC encoder and scene-camera stage head, scheme 3 only,
# and no simulator-labelled negatives (a robot has no simulator to play in)
RECIPE=(--stage-head-subtasks 3 --random-episodes 0 --wrong-order-episodes 0)
CAMERAS=(--camera ego=/sim0/camera/ego/image_raw/compressed --camera allo=/sim0/camera/allo/image_raw/compressed)
mkdir -p "$OUT" "$WORK"
STEPS="$OUT/steps.tsv"
[ -f "$STEPS" ] || printf 'step\tseconds\tcommand\n' >"$STEPS"
timed() {  # NAME DONE_MARK COMMAND...: run unless DONE_MARK exists, append its seconds
  local name=$1 done=$2
  shift 2
  if [ -e "$done" ]; then echo "rehearsal: $name done already ($done)"; return 0; fi
  echo "rehearsal: $name" >&2
  local began=$SECONDS
  "$@"
  printf '%s\t%s\t%s\n' "$name" "$((SECONDS - began))" "$*" >>"$STEPS"
}

timed record "$WORK/session/session.mcap" bash scripts/experiments/rehearsal/record_session.sh "$WORK/session" "$N"
timed import "$WORK/imported" "$BIN/inest-import-demos" "$WORK/session/session.mcap" --out "$WORK/imported" \
  --episode-times "$WORK/session/times.csv" "${CAMERAS[@]}"
timed template "$WORK/template.csv" "$BIN/inest-label-demos" "$WORK/imported" --template "$WORK/template.csv" \
  --sheets "$WORK/sheets"
timed labeller "$WORK/ends-labelled.csv" "$BIN/python" scripts/experiments/rehearsal/labeller_standin.py \
  "$WORK/session/ends-true.csv" "$WORK/imported" "$WORK/ends-labelled.csv" --error 2
timed label "$WORK/labelled.done" bash -c "'$BIN/inest-label-demos' '$WORK/imported' '$WORK/ends-labelled.csv' && touch '$WORK/labelled.done'"
timed collect-native "$WORK/native/metadata.json" "$BIN/inest-collect-demos" --out "$WORK/native" --episodes "$N"
timed collect-heldout "$WORK/heldout/metadata.json" "$BIN/inest-collect-demos" --out "$WORK/heldout" --episodes 40 \
  --seed 5000 --valid-fraction 0.5
for seed in ${INEST_REHEARSAL_SEEDS:-0 1 2}; do
  for arm in robot native; do
    data="$WORK/imported"
    [ "$arm" = robot ] || data="$WORK/native"
    name="$arm-seed$seed"
    timed "pretrain-$name" "$WORK/pretrain-$name/model/model.json" "$BIN/inest-pretrain" "$data" \
      --out "$WORK/pretrain-$name" "${RECIPE[@]}" --seed "$seed" --stage-head-seed "$seed" --classifier-seed "$seed"
    mkdir -p "$OUT/model-$name"
    cp "$WORK/pretrain-$name/model/"* "$OUT/model-$name/"
    timed "quality-$name" "$OUT/quality-$name/report.json" "$BIN/inest-reward-quality" "$OUT/model-$name" \
      "$WORK/heldout" --out "$OUT/quality-$name" --schemes 3
  done
done
# diagnostic, seed 0: the robot arm labelled with the true ends (what the labeller's +-2 frames cost)
if [ ! -d "$WORK/imported-true-ends" ]; then
  cp -r "$WORK/imported" "$WORK/imported-true-ends"
  "$BIN/inest-label-demos" "$WORK/imported-true-ends" "$WORK/session/ends-true.csv"
fi
timed pretrain-robot-true-ends-seed0 "$WORK/pretrain-robot-true-ends-seed0/model/model.json" "$BIN/inest-pretrain" \
  "$WORK/imported-true-ends" --out "$WORK/pretrain-robot-true-ends-seed0" "${RECIPE[@]}" --seed 0
mkdir -p "$OUT/model-robot-true-ends-seed0"
cp "$WORK/pretrain-robot-true-ends-seed0/model/"* "$OUT/model-robot-true-ends-seed0/"
timed quality-robot-true-ends-seed0 "$OUT/quality-robot-true-ends-seed0/report.json" "$BIN/inest-reward-quality" \
  "$OUT/model-robot-true-ends-seed0" "$WORK/heldout" --out "$OUT/quality-robot-true-ends-seed0" --schemes 3
# served: the robot model over the graph, the simulator sending JPEG cameras, a short training run
SERVE=(.venv/bin/inest-launch --model "$OUT/model-robot-seed0" --sims 1 --steps 300 --out "$WORK/serve"
  --param sim:image_transport:=compressed --param reward:image_transport:=compressed)
if [ ! -f "$OUT/serve/launch.txt" ]; then
  rm -rf "$WORK/serve"
  mkdir -p "$OUT/serve"
  { echo "# ${SERVE[*]}"; "${SERVE[@]}"; } >"$OUT/serve/launch.txt" 2>&1
  cp "$WORK/serve/reward_trace.png" "$OUT/serve/"
fi
cp "$WORK/session/times.csv" "$WORK/ends-labelled.csv" "$WORK/session/ends-true.csv" "$OUT/"
"$BIN/python" scripts/experiments/rehearsal/summarise.py "$OUT"
