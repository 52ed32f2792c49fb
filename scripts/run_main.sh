#!/usr/bin/env bash
# The main job, from a fresh clone: set up .venv (which also builds the ROS interfaces), then run
# the ROS 2 graph (2 simulators + reward node + agent) twice with the committed default reward
# model. First the committed trained policy places the blocks in order over ROS topics
# (runs/graph-trained/, INEST_TRAINED_EPISODES, default 6); then a fresh SAC agent trains briefly
# with live progress (runs/graph-main/, INEST_GRAPH_STEPS, default 4000). Each writes its reward
# trace (reward_trace.png). Building the dataset and a reward model from scratch instead:
# scripts/build_from_scratch.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
cd "$ROOT"
MODEL=results/long-horizon/reward-model-scene96-600demos   # the committed default reward model
POLICY=results/robot-reward/inest3-scene/seed2             # SAC trained on it with the defaults (results/README.md)
rm -rf runs/graph-trained runs/graph-main                  # fresh runs each time
echo "== the trained agent on the live graph: the subtask should climb to 3"
"$BIN/inest-launch" --out runs/graph-trained --model "$MODEL" --sims 2 \
  --param agent:mode:=evaluate --param "agent:policy:=$POLICY" \
  --param "agent:episodes:=${INEST_TRAINED_EPISODES:-6}" --episode-lines
echo "== a fresh agent learning over the graph (updates start after 1,000 steps)"
"$BIN/inest-launch" --out runs/graph-main --model "$MODEL" --sims 2 \
  --steps "${INEST_GRAPH_STEPS:-4000}" --param agent:sac.learning_starts:=1000 \
  --param agent:final_eval_episodes:=50
