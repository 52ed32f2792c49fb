#!/usr/bin/env bash
# The long-horizon result set: every cell below trained in runs/long-horizon/<method>/seed<N>/,
# two at a time on one torch/JAX thread each (INEST_PARALLEL, INEST_THREADS); a killed run resumes from its last checkpoint when
# this is run again, and a finished one is skipped. Then the small files of every run (results,
# config, plots; no checkpoints) are copied to results/long-horizon/ with summary.json and
# learning_curves.png (inest-summarise).
#   bash scripts/long_horizon.sh [METHOD ...]     # default: all methods
#   bash scripts/long_horizon.sh --collect        # only copy and summarise what runs/long-horizon holds
# Environment: INEST_MODEL (reward model folder, default results/long-horizon/reward-model),
# INEST_PIXEL_MODEL (the same with pixel stage heads, default results/long-horizon/reward-model-pixel),
# INEST_SCENE_MODEL (the same encoder with scene-camera stage heads, default results/long-horizon/reward-model-scene),
# INEST_SCENE96_MODEL (the same with 96 px scene-camera stage heads, default results/long-horizon/reward-model-scene96),
# INEST_SCENE96_600_MODEL (the same with the scene heads fitted on 600 demonstrations, default results/long-horizon/reward-model-scene96-600demos),
# INEST_ALLO96_MODEL (the allocentric encoder with 96 px stage heads on its own camera, default results/long-horizon/reward-model-allo96),
# INEST_SEEDS (default "0 1 2"), INEST_PARALLEL (default 2), INEST_THREADS (torch/JAX threads per run, default 1).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
MODEL="${INEST_MODEL:-results/long-horizon/reward-model}"
PIXEL_MODEL="${INEST_PIXEL_MODEL:-results/long-horizon/reward-model-pixel}"  # + pixel stage heads
SCENE_MODEL="${INEST_SCENE_MODEL:-results/long-horizon/reward-model-scene}"  # + stage heads on the allocentric camera
SCENE96_MODEL="${INEST_SCENE96_MODEL:-results/long-horizon/reward-model-scene96}"  # the same heads at 96 px
SCENE96_600_MODEL="${INEST_SCENE96_600_MODEL:-results/long-horizon/reward-model-scene96-600demos}"  # heads on 600 demonstrations
ALLO96_MODEL="${INEST_ALLO96_MODEL:-results/long-horizon/reward-model-allo96}"  # encoder and heads on the scene camera
THREE_FRAMES="--instant-confidence 1.0"  # the confirmation without its instant path: the default before 0.9
RUNS=runs/long-horizon
CONFIG=inest_agent_node/config/train.yaml

declare -A METHODS=(
  [oracle]="--reward env --total-steps 300000"
  [oracle-state-obs]="--reward env --observation state --total-steps 300000"
  [inest3-embedding]="--reward inest --model $MODEL --intrinsic embedding --stage-evidence embedding --total-steps 300000 $THREE_FRAMES"
  [inest3-none]="--reward inest --model $MODEL --intrinsic none --stage-evidence embedding --total-steps 300000 $THREE_FRAMES"
  [inest3-embedding-state-obs]="--reward inest --model $MODEL --intrinsic embedding --stage-evidence embedding --observation state --total-steps 300000 $THREE_FRAMES"
  [inest3-pixel-none]="--reward inest --model $PIXEL_MODEL --intrinsic none --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  [inest3-pixel-embedding]="--reward inest --model $PIXEL_MODEL --intrinsic embedding --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  [inest3-scene-none]="--reward inest --model $SCENE_MODEL --intrinsic none --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  [inest3-scene-embedding]="--reward inest --model $SCENE_MODEL --intrinsic embedding --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  [inest3-scene96-embedding]="--reward inest --model $SCENE96_MODEL --intrinsic embedding --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  # the same head with the two-speed confirmation: one frame at P >= 0.9 confirms at once (docs/reports/reward-signal.md, "The tracker's lag")
  [inest3-scene96-embedding-instant09]="--reward inest --model $SCENE96_MODEL --intrinsic embedding --stage-evidence pixels --instant-confidence 0.9 --total-steps 300000"
  # the same with heads fitted on 600 demonstrations for 3000 iterations (docs/reports/reward-signal.md, "The stage head's last frame")
  [inest3-scene96-600demos-embedding-instant09]="--reward inest --model $SCENE96_600_MODEL --intrinsic embedding --stage-evidence pixels --instant-confidence 0.9 --total-steps 300000"
  [inest3-scene96-600demos-none-instant09]="--reward inest --model $SCENE96_600_MODEL --intrinsic none --stage-evidence pixels --instant-confidence 0.9 --total-steps 300000"
  [inest3-scene96-embedding-state-obs]="--reward inest --model $SCENE96_MODEL --intrinsic embedding --stage-evidence pixels --observation state --total-steps 300000 $THREE_FRAMES"
  # one camera for all: the allocentric encoder (shaping) and its 96 px stage heads
  [inest3-allo96-embedding]="--reward inest --model $ALLO96_MODEL --view allo --intrinsic embedding --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  [inest3-allo96-none]="--reward inest --model $ALLO96_MODEL --view allo --intrinsic none --stage-evidence pixels --total-steps 300000 $THREE_FRAMES"
  # the same at 1M steps, evaluated every 50k, updates on a second thread: the wall-clock check of
  # a 1M-step run (INEST_PARALLEL=1, one thread: the updates take one core, the environments the other)
  [inest3-scene96-embedding-1m]="--reward inest --model $SCENE96_MODEL --intrinsic embedding --stage-evidence pixels --total-steps 1000000 --eval-every 50000 --overlap-updates $THREE_FRAMES"
  # the same with one gradient step per vector step (replay ratio 0.25, 250k updates in 1M steps): the
  # update no longer outlasts the environments' step, so a 1M-step run fits 90 minutes on 2 cores
  [inest3-scene96-embedding-1m-rr025]="--reward inest --model $SCENE96_MODEL --intrinsic embedding --stage-evidence pixels --total-steps 1000000 --eval-every 50000 --overlap-updates --gradient-steps 1 $THREE_FRAMES"
  # DIAGNOSTIC, never a method: the learned shaping with the stage and bonus of the true progress
  [inest3-privileged-stage]="--reward inest --model $MODEL --intrinsic embedding --stage-evidence embedding --stage-source privileged --total-steps 300000 $THREE_FRAMES"
)
collect_only=false
[ "${1:-}" = "--collect" ] && { collect_only=true; shift; }
selected=("$@")
[ ${#selected[@]} -gt 0 ] || selected=(oracle inest3-embedding inest3-none oracle-state-obs inest3-embedding-state-obs)

cells=()
for method in "${selected[@]}"; do
  [ -n "${METHODS[$method]+x}" ] || { echo "long_horizon: unknown method $method (${!METHODS[*]})" >&2; exit 2; }
  for seed in ${INEST_SEEDS:-0 1 2}; do cells+=("$method $seed"); done
done

run_cell() {
  local method=$1 seed=$2 out="$RUNS/$1/seed$2"
  [ -f "$out/results.json" ] && return 0
  local resume=()
  [ -f "$out/config.json" ] && resume=(--resume)
  mkdir -p "$RUNS/$method"
  # shellcheck disable=SC2086  # METHODS entries are flag lists
  "$BIN/inest-train" --config "$CONFIG" --out "$out" --seed "$seed" --threads "${INEST_THREADS:-1}" \
    ${METHODS[$method]} "${resume[@]}" >"$out.log" 2>&1 \
    || echo "long_horizon: $method seed $seed failed; see $out.log" >&2
}

running=0
$collect_only && cells=()
for cell in "${cells[@]}"; do
  # shellcheck disable=SC2086
  run_cell $cell &
  running=$((running + 1))
  if [ "$running" -ge "${INEST_PARALLEL:-2}" ]; then wait -n; running=$((running - 1)); fi
done
wait

for run in "$RUNS"/*/seed*/; do
  target="results/long-horizon/${run#"$RUNS"/}"
  mkdir -p "$target"
  for file in config.json results.json learning_curve.png coverage.png; do
    [ -f "$run/$file" ] && cp "$run/$file" "$target/"
  done
  rm -f "$target/history.json" "$target/diagnostics.json"
  if [ ! -f "$run/results.json" ]; then  # still training: its learning curve and reward diagnostics so far
    for file in history.json diagnostics.json; do
      [ -f "$run/checkpoint/$file" ] && cp "$run/checkpoint/$file" "$target/"
    done
  fi
done
"$BIN/inest-summarise" results/long-horizon
