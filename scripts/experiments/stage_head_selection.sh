#!/usr/bin/env bash
# Chooses the scene stage head's fitting settings on the selection set of tracker_selection.sh (the
# 100 validation demonstrations of runs/demos-select and negatives at seed offset 2,000,000): the
# 3-subtask head of the 96 px scene-head model refitted with more demonstrations and iterations
# and/or batches a quarter drawn from frames next to a stage change (stage_head_variants.py, models
# in runs/head-variants/), each scored with the default three-frame confirmation and with
# instant 0.9 (default/: three frames, instant_confidence 1). Writes results/reward-signal/stage-head-selection/<variant>/<setting>/report.json
# and <setting>.txt. The 200-demonstration head is tracker-selection/'s default and instant09;
# committed-600demos/ is results/long-horizon/reward-model-scene96-600demos, the chosen settings.
#   bash scripts/experiments/stage_head_selection.sh
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
MODEL=results/long-horizon/reward-model-scene96
OUT=results/reward-signal/stage-head-selection
[ -f runs/demos-select/metadata.json ] \
  || "$BIN/inest-collect-demos" --out runs/demos-select --episodes 250 --valid-fraction 0.4 --seed 5000000 --workers 2
declare -A VARIANTS=(
  [boundary25]="boundary_share=0.25"
  [demos600]="max_demos=600,iterations=3000"
  [demos600-boundary25]="max_demos=600,iterations=3000,boundary_share=0.25"
)
declare -A SETTINGS=([default]="--instant-confidence 1.0" [instant09]="--instant-confidence 0.9")
variants=()
for name in boundary25 demos600 demos600-boundary25; do variants+=("$name=${VARIANTS[$name]}"); done
"$BIN/python" scripts/experiments/stage_head_variants.py "$MODEL" runs/demos runs/head-variants "${variants[@]}"
score() {  # NAME MODEL
  mkdir -p "$OUT/$1"
  for setting in default instant09; do
    echo "stage_head_selection: $1 $setting" >&2
    # shellcheck disable=SC2086  # a flag list
    "$BIN/inest-reward-quality" "$2" runs/demos-select --out "$OUT/$1/$setting" --schemes 3 \
      --stage-evidence pixels --negative-seed-offset 2000000 ${SETTINGS[$setting]} >"$OUT/$1/$setting.txt"
  done
}
for name in boundary25 demos600 demos600-boundary25; do
  score "$name" "runs/head-variants/$name/model"
  cp "runs/head-variants/$name/variant.json" "$OUT/$name/"
done
# the committed model with the chosen settings as calibration defaults (every scheme's head refitted
# on 2 threads: the same settings as demos600, not the same weights)
score committed-600demos results/long-horizon/reward-model-scene96-600demos
