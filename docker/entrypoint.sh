#!/usr/bin/env bash
# Source ROS and the INEST workspace, then run the command (default: the launch file).
set -e
source /opt/ros/jazzy/setup.bash
source /inest/ros2_ws/install/setup.bash
exec "$@"
