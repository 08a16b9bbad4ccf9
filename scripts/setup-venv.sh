#!/usr/bin/env bash
# Python venv with the real interop peers the tests talk to: rclpy with Fast DDS
# (PyPI ros-* wheels, no ROS install), eclipse-zenoh, rosbags, mcap (+ ros2 support);
# numpy, scipy and numba for the proving-ground simulator (scripts/proving_ground/);
# pillow to read the screenshot of the HTML report (cli/tests/diagnose.rs).
# Idempotent: does nothing when the venv already has them all.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=${MRTWIN_VENV:-.venv}
packages=(ros-rclpy ros-std-msgs ros-diagnostic-msgs ros-rmw-fastrtps-cpp ros-rosgraph-msgs
          eclipse-zenoh rosbags mcap mcap-ros2-support numpy scipy numba pillow)
check='import rclpy, std_msgs.msg, diagnostic_msgs.msg, rosgraph_msgs.msg, zenoh, rosbags, mcap, mcap_ros2, numpy, scipy, numba, PIL'
if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c "$check" 2>/dev/null; then
  echo "venv $venv ready"
  exit 0
fi
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check "${packages[@]}"
"$venv/bin/python" -c "$check"
echo "venv $venv ready"
