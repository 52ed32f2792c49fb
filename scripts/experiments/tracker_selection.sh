#!/usr/bin/env bash
# Chooses the confirmed tracker's confirmation setting on data the reported figures never see: a
# demonstration set on layout seeds from 5,000,000 (its 100 validation demonstrations) and negatives
# at seed offset 2,000,000, with the 96 px scene head's model. Writes
# results/reward-signal/tracker-selection/<setting>/report.json and <setting>.txt.
#   bash scripts/experiments/tracker_selection.sh
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
MODEL=results/long-horizon/reward-model-scene96
OUT=results/reward-signal/tracker-selection
[ -f runs/demos-select/metadata.json ] \
  || "$BIN/inest-collect-demos" --out runs/demos-select --episodes 250 --valid-fraction 0.4 --seed 5000000 --workers 2
declare -A SETTINGS=(
  [default]="--instant-confidence 1.0"  # three frames: the default before instant 0.9
  [confirm1-conf08]="--confirm-steps 1 --stage-confidence 0.8 --instant-confidence 1.0"
  [instant08]="--instant-confidence 0.8"
  [instant09]="--instant-confidence 0.9"
  [instant095]="--instant-confidence 0.95"
)
mkdir -p "$OUT"
for setting in default confirm1-conf08 instant08 instant09 instant095; do
  echo "tracker_selection: $setting" >&2
  # shellcheck disable=SC2086  # a flag list
  "$BIN/inest-reward-quality" "$MODEL" runs/demos-select --out "$OUT/$setting" --schemes 3 \
    --stage-evidence pixels --negative-seed-offset 2000000 ${SETTINGS[$setting]} >"$OUT/$setting.txt"
done
