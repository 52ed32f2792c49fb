#!/usr/bin/env bash
# Record a demonstration session the way a robot team does, with the simulator as the robot: a
# lockstep simulator node publishing JPEG CompressedImage cameras, inest-record writing them to
# an MCAP bag, inest-teleop-standin at the controls (the expert with noise and pauses) keeping N
# successful takes and writing their wall-clock times and true subtask ends. About 1 s per take.
#   record_session.sh OUT_DIR [N]     # writes OUT_DIR/session.mcap, times.csv, ends-true.csv, logs
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)"
OUT=$1
N=${2:-50}
BIN="$ROOT/.venv/bin"
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-91}
mkdir -p "$OUT"
"$BIN/inest-sim-node" --ros-args -r __ns:=/sim0 -p mode:=lockstep -p image_transport:=compressed \
  -p max_steps:=150 -p publish_clock:=false >"$OUT/sim.log" 2>&1 &
SIM=$!
"$BIN/inest-record" "$OUT/session.mcap" --namespaces sim0 --images --image-transport compressed --overwrite \
  >"$OUT/record.log" 2>&1 &
RECORD=$!
trap 'kill -INT $RECORD $SIM 2>/dev/null || true' EXIT
sleep 3
"$BIN/inest-teleop-standin" --episodes "$N" --namespace sim0 --max-steps 150 \
  --times "$OUT/times.csv" --ends "$OUT/ends-true.csv" | tee "$OUT/teleop.log"
kill -INT $RECORD && wait $RECORD
kill -INT $SIM && wait $SIM || true
trap - EXIT
