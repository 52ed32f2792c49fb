#!/usr/bin/env bash
# The main job, from a fresh clone: set up .venv, collect a small demonstration dataset, write a
# GIF of one expert episode, pretrain a small TCC reward model on it and write its reward-quality
# report. Every step is cached: re-running reuses (or resumes) what is already in runs/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
cd "$ROOT"
"$BIN/inest-collect-demos" --out runs/demos-main --episodes "${INEST_EPISODES:-100}"
"$BIN/inest-export-video" runs/demos-main --out runs/expert_episode.gif
if [ ! -f runs/pretrain-main/model/model.json ]; then
  RESUME=()
  [ -f runs/pretrain-main/config.json ] && RESUME=(--resume)
  "$BIN/inest-pretrain" runs/demos-main --out runs/pretrain-main \
    --iterations "${INEST_PRETRAIN_ITERATIONS:-300}" "${RESUME[@]}"
fi
"$BIN/inest-reward-quality" runs/pretrain-main/model runs/demos-main --out runs/quality-main
