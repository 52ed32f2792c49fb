#!/usr/bin/env bash
# The egocentric-only reward at a labelling budget of 0, 10 and 50 labelled negative episodes:
# the committed egocentric TCC encoder (results/long-horizon/reward-model) recalibrated with
# 0, 5 + 5 and 30 + 20 random-play + wrong-order episodes (runs/ego-labels/labels<N>/), then the
# stage filter chosen on the selection set (100 validation demonstrations of runs/demos-select,
# layout seeds from 5,000,000; negatives at seed offset 2,000,000), then every budget's held-out
# report (200 validation demonstrations of runs/demos, 40 + 40 negatives) with and without it.
# Reports go to results/robot-reward/label-budget/{selection,held-out}/<name>/ with <name>.txt.
# `window`: the window stage classifier (offsets 0 2 4 8 16) with no labelled episode and with the
# labelling path's 10 file-labelled ones, fitted without and with 200 rewound and 200 reordered
# demonstrations (runs/ego-labels/labels<B>-window-demo<N>/), on the selection set, read alone (three
# frames confirm, or one: -confirm1) and through the forward filter (labels<B>-window-demo<N>[-forward|-confirm1]);
# and the 10 episodes fitting the window classifier only, the thresholds left at the demonstrations'
# (labels10-window-demo200-demothresholds).
#   bash scripts/experiments/ego_label_budget.sh [models|selection|held-out|window]   # default: the first three
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
OUT=results/robot-reward/label-budget
declare -A NEGATIVES=([0]="0 0" [10]="5 5" [50]="30 20")  # random-play, wrong-order episodes
declare -A FILTERS=(
  [none]=""
  [forward]="--stage-filter forward"
  [forward-strict]="--stage-filter forward --filter-advance 0.02 --filter-temperature 0.3"
  # the filter already asks for agreement over frames: one filtered frame confirms
  [forward-confirm1]="--stage-filter forward --confirm-steps 1"
  [forward-fast-confirm1]="--stage-filter forward --filter-advance 0.1 --confirm-steps 1"
)
EVIDENCE=(--stage-evidence embedding)  # where the stage is read; the window stage sets its own
stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(models selection held-out)

report() {  # NAME MODEL DATASET [options...]
  local name=$1 model=$2 dataset=$3
  shift 3
  [ -f "$name/report.json" ] && return
  rm -rf "$name"
  "$BIN/inest-reward-quality" "$model" "$dataset" --out "$name" --schemes 3 "${EVIDENCE[@]}" "$@" >"$name.txt"
}

CLIPS=results/robot-reward/labelling-path/negatives/labelled.npz
window_model() {  # NAME DEMO_NEGATIVES [labelled-episode flags...]: the window classifier, recalibrated once
  local name=$1 count=$2
  shift 2
  [ -f "runs/ego-labels/$name/model/model.json" ] && return
  rm -rf "runs/ego-labels/$name"
  "$BIN/inest-pretrain" runs/demos --out "runs/ego-labels/$name" --recalibrate results/long-horizon/reward-model \
    --random-episodes 0 --wrong-order-episodes 0 --stage-head-iterations 0 --threads 1 \
    --stage-window-offsets 0 2 4 8 16 --demo-negatives "$count" "$@"
}

for stage in "${stages[@]}"; do
  case $stage in
    models)
      for budget in 0 10 50; do
        read -r random wrong <<<"${NEGATIVES[$budget]}"
        [ -f "runs/ego-labels/labels$budget/model/model.json" ] && continue
        rm -rf "runs/ego-labels/labels$budget"
        "$BIN/inest-pretrain" runs/demos --out "runs/ego-labels/labels$budget" --recalibrate results/long-horizon/reward-model \
          --random-episodes "$random" --wrong-order-episodes "$wrong" --stage-head-iterations 0 --threads 1
      done ;;
    selection)
      [ -f runs/demos-select/metadata.json ] \
        || "$BIN/inest-collect-demos" --out runs/demos-select --episodes 250 --valid-fraction 0.4 --seed 5000000 --workers 2
      mkdir -p "$OUT/selection"
      for budget in 0 10 50; do
        for filter in none forward forward-strict forward-confirm1 forward-fast-confirm1; do
          # shellcheck disable=SC2086  # a flag list
          report "$OUT/selection/labels$budget-$filter" "runs/ego-labels/labels$budget/model" runs/demos-select \
            --negative-seed-offset 2000000 ${FILTERS[$filter]}
        done
      done ;;
    held-out)
      mkdir -p "$OUT/held-out"
      for budget in 0 10 50; do
        for filter in none "${EGO_FILTER:-forward}"; do
          # shellcheck disable=SC2086
          report "$OUT/held-out/labels$budget-$filter" "runs/ego-labels/labels$budget/model" runs/demos ${FILTERS[$filter]}
        done
      done ;;
    window)
      mkdir -p "$OUT/selection"
      EVIDENCE=(--stage-evidence window)
      # 10: the labelling path's file-labelled episodes (labelling_path_timing.sh negatives), raising the thresholds
      declare -A LABELLED=([0]="" [10]="--clips $CLIPS --clips-raise-thresholds")
      for budget in 0 10; do
        for count in 0 200; do
          name=labels$budget-window-demo$count
          # shellcheck disable=SC2086  # a flag list
          window_model "$name" "$count" ${LABELLED[$budget]}
          report "$OUT/selection/$name" "runs/ego-labels/$name/model" runs/demos-select --negative-seed-offset 2000000
          report "$OUT/selection/$name-forward" "runs/ego-labels/$name/model" runs/demos-select \
            --negative-seed-offset 2000000 --stage-filter forward
          report "$OUT/selection/$name-confirm1" "runs/ego-labels/$name/model" runs/demos-select \
            --negative-seed-offset 2000000 --confirm-steps 1
        done
      done
      # the same 10 episodes fitting the classifier only, the thresholds left where the demonstrations
      # set them: what raising them costs the shaping's rho
      name=labels10-window-demo200-demothresholds
      window_model "$name" 200 --clips "$CLIPS"
      report "$OUT/selection/$name" "runs/ego-labels/$name/model" runs/demos-select --negative-seed-offset 2000000 ;;
    *) echo "ego_label_budget: unknown stage $stage (models, selection, held-out, window)" >&2; exit 2 ;;
  esac
done
