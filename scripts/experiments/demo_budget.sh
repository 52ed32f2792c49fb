#!/usr/bin/env bash
# How many demonstrations the reward needs: the TCC encoder and its goals pretrained on the first
# N of 800 training demonstrations (N = 25 50 100 200 800; the dataset's 200 validation ones for
# the encoder's validation loss), each then calibrated for one camera (the stage head on the wrist
# camera, --stage-head-view ego) and for two (on the scene camera), and judged by
# inest-reward-quality on the same 40 held-out demonstrations (seeds from 5000) and the same
# random and wrong-order play. Finished cells are skipped and an interrupted pretraining resumes,
# so the script can be run again until it is done.
#   bash scripts/experiments/demo_budget.sh [OUT]   # OUT default results/demo-budget
# Work files go to runs/demo-budget; about 25 minutes per cell on 2 cores.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
OUT=${1:-results/demo-budget}
WORK=${INEST_BUDGET_WORK:-runs/demo-budget}
BIN=.venv/bin
SIZES=${INEST_BUDGET_SIZES:-"50 800 25 100 200"}
# calibrated as a robot user can: no simulator-labelled negatives
CALIBRATION=(--random-episodes 0 --wrong-order-episodes 0 --stage-head-subtasks 3)
mkdir -p "$OUT" "$WORK"
[ -f "$WORK/demos/metadata.json" ] && [ "$(python3 -c "import json;print(json.load(open('$WORK/demos/metadata.json'))['complete'])")" = True ] \
  || "$BIN/inest-collect-demos" --out "$WORK/demos" --episodes 1000
[ -f "$WORK/heldout/metadata.json" ] || "$BIN/inest-collect-demos" --out "$WORK/heldout" --episodes 80 --seed 5000 --valid-fraction 0.5
for n in $SIZES; do
  for cameras in two one; do
    view=allo
    [ "$cameras" = two ] || view=ego
    run="$WORK/n$n-$cameras"
    if [ ! -f "$run/model/model.json" ]; then
      resume=()
      [ -f "$run/train_state.pt" ] && resume=(--resume)
      "$BIN/inest-pretrain" "$WORK/demos" --out "$run" --train-limit "$n" --stage-head-view "$view" \
        "${CALIBRATION[@]}" "${resume[@]}"
    fi
    mkdir -p "$OUT/n$n-$cameras"
    cp "$run/model/"* "$OUT/n$n-$cameras/"
    [ -f "$OUT/n$n-$cameras/quality/report.json" ] || "$BIN/inest-reward-quality" "$OUT/n$n-$cameras" \
      "$WORK/heldout" --out "$OUT/n$n-$cameras/quality" --schemes 3
  done
done
