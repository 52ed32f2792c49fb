#!/usr/bin/env bash
# Every reward-quality report of docs/reports/reward-signal.md, one after another, from the committed
# models and the demonstration set of `inest-collect-demos --out runs/demos --episodes 1000`:
# results/reward-signal/<report>/ (report.json, plots) and the printed table beside it as <report>.txt.
#   bash scripts/experiments/quality_reports.sh [REPORT ...]   # default: all of them
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
MODELS=results/long-horizon
OUT=results/reward-signal
PIXELS=(--stage-evidence pixels)
PRIVILEGED=(--stage-source privileged)
THREE_FRAMES=(--instant-confidence 1.0)  # the confirmation without its instant path (the default before 0.9)

declare -A REPORTS=(
  [quality-default]="$MODELS/reward-model --schemes 3 ${THREE_FRAMES[*]}"
  [quality-thesis]="$MODELS/reward-model --schemes 3 --shaping thesis --tracker threshold"
  [quality-pixel]="$MODELS/reward-model-pixel --schemes 3 ${PIXELS[*]} ${THREE_FRAMES[*]}"
  [quality-scene]="$MODELS/reward-model-scene --schemes 3 ${PIXELS[*]} ${THREE_FRAMES[*]}"
  [quality-scene96]="$MODELS/reward-model-scene96 --schemes 3 ${PIXELS[*]} ${THREE_FRAMES[*]}"
  [quality-scene96-confirm1]="$MODELS/reward-model-scene96 --schemes 3 ${PIXELS[*]} --confirm-steps 1 ${THREE_FRAMES[*]}"
  [quality-scene96-confirm1-conf08]="$MODELS/reward-model-scene96 --schemes 3 ${PIXELS[*]} --confirm-steps 1 --stage-confidence 0.8 ${THREE_FRAMES[*]}"
  [quality-scene96-confirm2]="$MODELS/reward-model-scene96 --schemes 3 ${PIXELS[*]} --confirm-steps 2 ${THREE_FRAMES[*]}"
  [quality-scene96-instant09]="$MODELS/reward-model-scene96 --schemes 3 ${PIXELS[*]} --instant-confidence 0.9"
  [quality-scene96-600demos]="$MODELS/reward-model-scene96-600demos --schemes 3 ${PIXELS[*]} ${THREE_FRAMES[*]}"
  [quality-scene96-600demos-instant09]="$MODELS/reward-model-scene96-600demos --schemes 3 ${PIXELS[*]} --instant-confidence 0.9"
  [quality-scene96-privileged]="$MODELS/reward-model-scene96 --schemes 3 ${PIXELS[*]} ${PRIVILEGED[*]}"
  [allo-encoder/quality]="$OUT/allo-encoder/model --schemes 1 3 --stage-evidence embedding ${THREE_FRAMES[*]}"
  [allo-encoder/quality-pixels]="$OUT/allo-encoder/model --schemes 3 ${PIXELS[*]} ${THREE_FRAMES[*]}"
  [quality-allo96]="$MODELS/reward-model-allo96 --schemes 3 ${PIXELS[*]} ${THREE_FRAMES[*]}"
  [quality-allo96-privileged]="$MODELS/reward-model-allo96 --schemes 3 ${PIXELS[*]} ${PRIVILEGED[*]}"
)
selected=("$@")
[ ${#selected[@]} -gt 0 ] || selected=("${!REPORTS[@]}")
for report in "${selected[@]}"; do
  [ -n "${REPORTS[$report]+x}" ] || { echo "quality_reports: unknown report $report (${!REPORTS[*]})" >&2; exit 2; }
  read -r model options <<<"${REPORTS[$report]}"
  echo "quality_reports: $report" >&2
  rm -rf "${OUT:?}/$report"
  # shellcheck disable=SC2086  # options is a flag list
  "$BIN/inest-reward-quality" "$model" runs/demos --out "$OUT/$report" $options >"$OUT/$report.txt"
done
