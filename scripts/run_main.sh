#!/usr/bin/env bash
# The main job, from a fresh clone: set up .venv, collect a small demonstration dataset
# (cached: re-running resumes or reuses it) and write a GIF of one expert episode.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
BIN="${INEST_VENV:-$ROOT/.venv}/bin"
cd "$ROOT"
"$BIN/inest-collect-demos" --out runs/demos-small --episodes "${INEST_EPISODES:-20}"
"$BIN/inest-export-video" runs/demos-small --out runs/expert_episode.gif
