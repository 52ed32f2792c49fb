#!/usr/bin/env bash
# The whole test suite (lint included), from a fresh clone: set up .venv, then ruff and pytest.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
cd "$ROOT"
"$BIN/ruff" check .
"$BIN/ruff" format --check .
"$BIN/pytest" "$@"
