#!/usr/bin/env bash
# Every benchmark of benchmarks/ once, one after another, for an otherwise idle machine: each
# benchmark's JSON line goes to OUT/<name>.json together with the 1-minute load average before
# and after it and the revision it ran on. With BASE_REV, the in-process benchmarks also run on
# that revision (a git worktree, its packages first on the path) into OUT/base/, alternating
# with this tree's, so a refactoring can be shown to leave the speed unchanged.
#   bash scripts/experiments/speed_check.sh [BASE_REV] [OUT]   # OUT default results/benchmarks
# Environment: INEST_MODEL (reward model folder, default the committed default model),
# INEST_ONLY (benchmark names to run, e.g. "graph_train_speed reward_node_flood"; default all).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
BASE=${1:-}
OUT=$(realpath -m "${2:-$ROOT/results/benchmarks}")
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
MODEL=$(realpath "${INEST_MODEL:-results/long-horizon/reward-model-scene96-600demos}")
mkdir -p "$OUT"
for name in ${INEST_ONLY:-}; do
  [ -f "benchmarks/$name.py" ] || { echo "speed_check: no benchmark $name (INEST_ONLY)" >&2; exit 2; }
done

measure() {  # TREE OUT_FILE SCRIPT [ARG ...]: one benchmark of TREE, its JSON plus the load
  local tree=$1 file=$2 script=$3
  shift 3
  [ -z "${INEST_ONLY:-}" ] || [[ " $INEST_ONLY " == *" ${script%.py} "* ]] || return 0
  local path="$tree/inest_common:$tree/inest_sim_node:$tree/inest_reward_node:$tree/inest_agent_node:$tree/ros2_ws/src/inest_bringup"
  local before revision
  before=$(cut -d' ' -f1 /proc/loadavg)
  revision=$(git -C "$tree" rev-parse --short HEAD)
  echo "speed_check: $script $* ($revision)" >&2
  (cd "$tree" && PYTHONPATH="$path" "$BIN/python" "benchmarks/$script" "$@") 2>"$file.log" | tail -n 1 >"$file.tmp" \
    || { echo "speed_check: $script failed; see $file.log" >&2; rm -f "$file.tmp"; return 0; }
  "$BIN/python" - "$file.tmp" "$file" "$before" "$(cut -d' ' -f1 /proc/loadavg)" "$revision" "$*" <<'EOF'
import json, sys
tmp, out, before, after, revision, arguments = sys.argv[1:]
result = json.loads(open(tmp).read())
result["measured"] = {"revision": revision, "arguments": arguments,
                      "load_1min_before": float(before), "load_1min_after": float(after)}
open(out, "w").write(json.dumps(result, indent=2) + "\n")
EOF
  rm -f "$file.tmp" "$file.log"
}

in_process=("env_speed.py" "encoder_speed.py small_cnn" "train_speed.py $MODEL")
if [ -n "$BASE" ]; then
  tree="$ROOT/runs/speed-check-base"
  [ -d "$tree" ] || git worktree add -q --detach "$tree" "$BASE"
  mkdir -p "$OUT/base"
fi
for entry in "${in_process[@]}"; do
  read -r script arguments <<<"$entry"
  name=${script%.py}
  # shellcheck disable=SC2086  # arguments is a word list
  [ -z "$BASE" ] || measure "$tree" "$OUT/base/$name.json" "$script" $arguments
  # shellcheck disable=SC2086
  measure "$ROOT" "$OUT/$name.json" "$script" $arguments
done
measure "$ROOT" "$OUT/learner_speed.json" learner_speed.py
measure "$ROOT" "$OUT/reward_node_speed.json" reward_node_speed.py "$MODEL"
measure "$ROOT" "$OUT/reward_node_flood.json" reward_node_flood.py "$MODEL"
measure "$ROOT" "$OUT/reward_node_cameras.json" reward_node_cameras.py "$MODEL"
measure "$ROOT" "$OUT/graph_train_speed.json" graph_train_speed.py "$MODEL"
measure "$ROOT" "$OUT/million_step_speed.json" million_step_speed.py "$(realpath results/long-horizon/reward-model-scene96)"
measure "$ROOT" "$OUT/import_speed.json" import_speed.py
