#!/usr/bin/env bash
# colcon-build the whole ROS 2 workspace (ros2_ws/) against the pip-installed ROS wheels, as a
# ROS install would build it (CI runs this; the Docker image does the same on ros:jazzy).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${INEST_VENV:-$ROOT/.venv}"
cd "$ROOT/ros2_ws"
PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" "$VENV/bin/colcon" --log-base log build \
  --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$VENV/bin/python" "$@"
