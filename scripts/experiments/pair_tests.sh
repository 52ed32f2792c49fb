#!/usr/bin/env bash
# Welch t tests of the method pairs the reports compare outside their bonus tables (each pair
# one test, uncorrected; scripts/experiments/bonus_effect.py compares any two method folders):
# the robot-reward departure chain, the loop rows and the agent target's pairs
# (results/robot-reward/pair-tests.json), and the long-horizon stage-detector and
# observation pairs (results/long-horizon/pair-tests.json).
#   bash scripts/experiments/pair_tests.sh
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
PY="${INEST_VENV:-$ROOT/.venv}/bin/python"
R=results/robot-reward
"$PY" scripts/experiments/bonus_effect.py \
  "$R/ego10-embedding:results/thesis-method/thesis-embedding" "$R/inest3-scene:$R/ego10-embedding" \
  "$R/inest3-scene-weight1:$R/inest3-scene" "$R/oracle:$R/inest3-scene-weight1" "$R/oracle:$R/inest3-scene" \
  "$R/ego10-embedding:$R/ego10-none" \
  "$R/ego-loop10-embedding:$R/ego0-selfneg" "$R/ego-loop10-embedding:$R/ego-loop10-classifier-embedding" \
  "$R/ego-loop10-embedding:$R/ego-loop10-none" "$R/ego10-embedding:$R/ego-loop10-embedding" \
  --out "$R/pair-tests.json"
L=results/long-horizon
"$PY" scripts/experiments/bonus_effect.py \
  "$L/inest3-scene-embedding:$L/inest3-embedding" "$L/inest3-scene96-embedding:$L/inest3-scene96-embedding-state-obs" \
  --out "$L/pair-tests.json"
