#!/usr/bin/env bash
# The whole test suite (lint included), from a fresh clone: set up .venv, then ruff and pytest.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
cd "$ROOT"
"$BIN/ruff" check .
"$BIN/ruff" format --check .
bash "$ROOT/scripts/colcon_build.sh" >/dev/null || { echo "run_tests: colcon build of ros2_ws failed" >&2; exit 1; }
echo "run_tests: colcon build of ros2_ws succeeded" >&2
"$BIN/pytest" "$@"
