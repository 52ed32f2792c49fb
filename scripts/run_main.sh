#!/usr/bin/env bash
# The main job, from a fresh clone: set up .venv (which also builds the ROS interfaces), collect
# a small demonstration dataset, write a GIF of one expert episode, pretrain a small TCC reward
# model and write its reward-quality report (all cached in runs/), then launch the ROS 2 graph
# (2 simulators + reward node + SAC agent) for a bounded number of training steps with live
# progress, and write the reward trace (runs/graph-main/reward_trace.png).
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
# A fresh agent run each time (runs/graph-main is replaced); updates start after 1,000 steps.
rm -rf runs/graph-main
"$BIN/inest-launch" --out runs/graph-main --model runs/pretrain-main/model --sims 2 \
  --steps "${INEST_GRAPH_STEPS:-4000}" --param agent:sac.learning_starts:=1000 \
  --param agent:final_eval_episodes:=50
