#!/usr/bin/env bash
# Which egocentric TCC representation's distance falls steadily inside every subtask? Pretrains the
# encoder in several variants on one demonstration set, all at once, then scores each with
# inest-reward-quality (3 subtasks) with its own tracker and with the true stage, and gathers the
# per-subtask figures into OUT/representation.json (representation_summary.py).
#   bash scripts/experiments/representation_probe.sh OUT [DEVICE]   # DEVICE: cpu (default) or cuda
# Variants: base (the defaults), long (4x the iterations), strong-aug (shift 8 px, brightness and
# contrast 0.4), deep (six strided convolutions), resnet18. Calibration fits no pixel stage head
# (the representation is what is measured; the trackers read the embedding's stage classifier).
# Environment: INEST_PYTHON (default .venv/bin/python), INEST_EPISODES (default 1000),
# INEST_ITERATIONS (default 1500), INEST_VARIANTS (default: all five), INEST_NEGATIVES (default 40),
# INEST_SIZE_FLAGS (extra inest-pretrain flags for every variant, e.g. a small image for a smoke test).
# The five run side by side on 2 threads each (ResNet-18: 6), sized for a 16-core machine.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
OUT=$(realpath -m "${1:?usage: representation_probe.sh OUT [DEVICE]}")
DEVICE=${2:-cpu}
PY=${INEST_PYTHON:-$ROOT/.venv/bin/python}
ITERATIONS=${INEST_ITERATIONS:-1500}
export PYTHONPATH="$ROOT/inest_common:$ROOT/inest_sim_node:$ROOT/inest_reward_node${PYTHONPATH:+:$PYTHONPATH}"
export MPLBACKEND=Agg
mkdir -p "$OUT"
cd "$OUT"
[ -f demos/metadata.json ] || "$PY" -m inest_sim_node.collect --out demos --episodes "${INEST_EPISODES:-1000}" \
  --workers "$(nproc)" >collect.log 2>&1

declare -A VARIANTS=(
  [base]=""
  [long]="--iterations $((4 * ITERATIONS))"
  [strong-aug]="--augment-shift 8 --augment-brightness 0.4 --augment-contrast 0.4"
  [deep]="--widths 32,64,64,64,128,128"
  [resnet18]="--encoder resnet18"
)
variant() {  # NAME: pretrain, then the reward-quality report with its tracker and with the true stage
  local name=$1 threads=2
  [ "$name" = resnet18 ] && threads=6  # its calibration and reports embed ~90k frames on the CPU
  export OMP_NUM_THREADS=$threads
  # shellcheck disable=SC2086  # flag lists
  "$PY" -m inest_reward_node.learning.pretrain demos --out "$name" --device "$DEVICE" --threads "$threads" \
    --iterations "$ITERATIONS" --stage-head-iterations 0 ${INEST_SIZE_FLAGS:-} ${VARIANTS[$name]} >"$name.log" 2>&1
  for stage in tracker privileged; do
    "$PY" -m inest_reward_node.learning.quality "$name/model" demos --out "$name/quality-$stage" --schemes 3 \
      --negative-episodes "${INEST_NEGATIVES:-40}" --stage-source "$stage" >>"$name.log" 2>&1
  done
}
for name in ${INEST_VARIANTS:-base long strong-aug deep resnet18}; do
  [ -n "${VARIANTS[$name]+x}" ] || { echo "representation_probe: unknown variant $name" >&2; exit 2; }
  variant "$name" || echo "representation_probe: $name failed; see $OUT/$name.log" >&2 &
done
wait
"$PY" "$ROOT/scripts/experiments/representation_summary.py" "$OUT" | tee "$OUT/representation.json"
