#!/usr/bin/env bash
# Create the virtual environment (default .venv, or $INEST_VENV) and install everything pinned.
# Re-running is cheap: it reinstalls only when a requirements or setup file changed.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${INEST_VENV:-$ROOT/.venv}"
PYTHON="${PYTHON:-$(command -v python3.11 || command -v python3)}"
"$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))' \
  || { echo "setup_env: Python 3.11 or newer is needed, $PYTHON is $("$PYTHON" --version)" >&2; exit 1; }

cd "$ROOT"
STAMP="$(cat requirements.txt requirements-dev.txt scripts/setup_env.sh scripts/fix_ros_wheel_cmake.py inest_*/setup.py \
  inest_*/setup.cfg ros2_ws/src/inest_bringup/setup.py ros2_ws/src/inest_interfaces/CMakeLists.txt \
  ros2_ws/src/inest_interfaces/*/*.* | sha256sum | cut -d' ' -f1)"
[ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
if [ "$(cat "$VENV/.inest-stamp" 2>/dev/null)" != "$STAMP" ]; then
  echo "setup_env: installing pinned dependencies into $VENV" >&2
  "$VENV/bin/python" -m pip install -q --upgrade pip
  "$VENV/bin/python" -m pip install -q torch==2.13.0
  "$VENV/bin/python" -m pip install -q -r requirements.txt -r requirements-dev.txt
  "$VENV/bin/python" -m pip install -q --no-deps -e inest_common -e inest_sim_node -e inest_reward_node -e inest_agent_node \
    -e ros2_ws/src/inest_bringup
  # after inest_agent_node: in a venv from before inest_experiments existed, inest_agent_node's
  # install record lists inest-evaluate & co., and reinstalling it deletes them
  "$VENV/bin/python" -m pip install -q --no-deps -e inest_experiments
  # Editable installs resolve through import hooks that Python consults only after sys.path: from
  # the repository root an ament package folder such as ./inest_sim_node/ (no __init__.py) would win as an
  # empty namespace package. A path entry per package folder makes the real package win everywhere.
  SITE="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  printf '%s\n' "$ROOT/inest_common" "$ROOT/inest_sim_node" "$ROOT/inest_reward_node" "$ROOT/inest_agent_node" \
    "$ROOT/inest_experiments" >"$SITE/inest-packages.pth"
  # The ROS interfaces, generated and compiled from the wheels straight into the venv prefix
  # (no environment variables needed at run time).
  "$VENV/bin/python" scripts/fix_ros_wheel_cmake.py "$VENV"
  BUILD="$VENV/build/inest_interfaces"
  rm -rf "$BUILD" && mkdir -p "$BUILD"
  (cd "$BUILD" && PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" cmake "$ROOT/ros2_ws/src/inest_interfaces" \
      -DCMAKE_INSTALL_PREFIX="$VENV" -DCMAKE_PREFIX_PATH="$VENV" -DPython3_EXECUTABLE="$VENV/bin/python" \
      -DBUILD_TESTING=OFF >cmake.log 2>&1 && make -j2 install >make.log 2>&1) \
    || { echo "setup_env: building inest_interfaces failed; see $BUILD/*.log" >&2; exit 1; }
  echo "$STAMP" > "$VENV/.inest-stamp"
fi
