#!/usr/bin/env bash
# Does an idle node exit on SIGTERM? Starts inest-sim-node N times (default 40) on a private ROS
# domain, sends SIGTERM after 2-4 s of idle spinning, and counts the processes still alive 5 s later
# (those are then killed). Prints one line per run and the count.
#   bash scripts/experiments/sigterm_check.sh [N]
set -uo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
RUNS=${1:-40}
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-77}
LOGS=$(mktemp -d)
hung=0
for run in $(seq 1 "$RUNS"); do
  "$BIN/inest-sim-node" --ros-args -r "__ns:=/check$run" -p "cameras:=[ego]" >"$LOGS/$run.log" 2>&1 &
  pid=$!
  sleep $((2 + run % 3))
  kill -TERM "$pid"
  for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
  if kill -0 "$pid" 2>/dev/null; then
    hung=$((hung + 1))
    kill -KILL "$pid"
  fi
  wait "$pid"
  echo "run $run: exit status $?"
done
echo "sigterm_check: $hung of $RUNS idle simulators still running 5 s after SIGTERM"
rm -rf "$LOGS"
