#!/usr/bin/env bash
# Behaviour check for a refactoring: the same small pipeline run on two revisions gives the same
# numbers. Pretraining (a tiny TCC model on a tiny dataset), its reward-quality report, and a short
# INEST training run on the committed reward model, each with fixed seeds on one thread; then the
# JSON outputs are compared with timings and paths left out (compare_runs.py).
#   bash scripts/experiments/behaviour_check.sh BASE_REV [OUT]    # OUT default runs/behaviour-check
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BASE=${1:?usage: behaviour_check.sh BASE_REV [OUT]}
OUT=$(realpath -m "${2:-$ROOT/runs/behaviour-check}")
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
MODEL="$ROOT/results/long-horizon/reward-model"
mkdir -p "$OUT"
[ -d "$OUT/base-tree" ] || git -C "$ROOT" worktree add -q --detach "$OUT/base-tree" "$BASE"
[ -d "$OUT/demos" ] || "$BIN/inest-collect-demos" --out "$OUT/demos" --episodes 8 --image-size 48 --workers 1 >"$OUT/demos.log" 2>&1

pipeline() {  # TREE NAME: the pipeline with TREE's packages first on the path
  local tree=$1 out="$OUT/$2"
  local path="$tree/inest_sim_node:$tree/inest_reward_node:$tree/inest_agent_node"
  [ -d "$tree/inest_common" ] && path="$tree/inest_common:$path"
  rm -rf "$out" && mkdir -p "$out"
  export PYTHONPATH="$path"
  "$BIN/inest-pretrain" "$OUT/demos" --out "$out/pretrain" --image-size 48 --iterations 30 --videos-per-batch 4 \
    --frames-per-video 16 --validate-every 10 --checkpoint-every 30 --random-episodes 4 --wrong-order-episodes 2 \
    --seed 0 --threads 1 >"$out/pretrain.log" 2>&1
  "$BIN/inest-reward-quality" "$out/pretrain/model" "$OUT/demos" --out "$out/quality" --negative-episodes 4 \
    >"$out/quality.log" 2>&1
  "$BIN/inest-train" --out "$out/train" --reward inest --model "$MODEL" --intrinsic embedding --total-steps 2000 \
    --eval-every 1000 --eval-episodes 4 --final-eval-episodes 8 --checkpoint-every 2000 --seed 0 --threads 1 \
    >"$out/train.log" 2>&1
  unset PYTHONPATH
}
pipeline "$OUT/base-tree" base
pipeline "$ROOT" head
"$BIN/python" "$ROOT/scripts/experiments/compare_runs.py" "$OUT/base" "$OUT/head" | tee "$OUT/comparison.json"
