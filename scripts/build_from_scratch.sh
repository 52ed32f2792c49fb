#!/usr/bin/env bash
# Everything the main job takes from the repository, built from scratch at a small size: a
# demonstration dataset from the scripted expert (runs/demos-main/, INEST_EPISODES, default 100),
# a GIF of one expert episode (runs/expert_episode.gif), a TCC reward model with the pixel stage
# head of the 3-subtask scheme the graph uses (runs/pretrain-main/, INEST_PRETRAIN_ITERATIONS,
# default 300; an interrupted run resumes), its reward-quality report (runs/quality-main/), then
# a fresh SAC agent training on it over the ROS 2 graph (runs/graph-scratch/, INEST_GRAPH_STEPS,
# default 4000). Re-running reuses the dataset and the model.
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
  "$BIN/inest-pretrain" runs/demos-main --out runs/pretrain-main --stage-head-subtasks 3 \
    --iterations "${INEST_PRETRAIN_ITERATIONS:-300}" "${RESUME[@]}"
fi
"$BIN/inest-reward-quality" runs/pretrain-main/model runs/demos-main --out runs/quality-main --schemes 3
rm -rf runs/graph-scratch
"$BIN/inest-launch" --out runs/graph-scratch --model runs/pretrain-main/model --sims 2 \
  --steps "${INEST_GRAPH_STEPS:-4000}" --param agent:sac.learning_starts:=1000 \
  --param agent:final_eval_episodes:=50
