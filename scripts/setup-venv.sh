#!/usr/bin/env bash
# Python venv with the real interop peers the tests talk to: rclpy with Fast DDS
# (PyPI ros-* wheels, no ROS install), eclipse-zenoh, rosbags, mcap (+ ros2 support);
# numpy, scipy and numba for the proving-ground simulator (scripts/proving_ground/);
# websockets for the Foxglove live-view client (examples/foxglove-client/);
# pillow to read the screenshot of the HTML report (cli/tests/diagnose.rs).
# Idempotent: does nothing when the venv already has them all.
set -euo pipefail
cd "$(dirname "$0")/.."
# MRTWIN_ROS_DISTRO=jazzy (with e.g. MRTWIN_VENV=.venv-jazzy): a second venv with the ROS 2
# Jazzy wheels (ros-jazzy-*) and nothing else, for the rclpy interop matrix (docs/ros2.md).
venv=${MRTWIN_VENV:-.venv}
if [ "${MRTWIN_ROS_DISTRO:-}" = jazzy ]; then
  packages=(ros-jazzy-rclpy ros-jazzy-std-msgs ros-jazzy-diagnostic-msgs
            ros-jazzy-rmw-fastrtps-cpp ros-jazzy-rosgraph-msgs)
  check='import rclpy, std_msgs.msg, diagnostic_msgs.msg, rosgraph_msgs.msg'
elif [ -n "${MRTWIN_ROS_DISTRO:-}" ]; then
  echo "error: MRTWIN_ROS_DISTRO=${MRTWIN_ROS_DISTRO}: only 'jazzy' (or unset for the default wheels)" >&2
  exit 2
else
  # The proving ground's numerics are pinned: its scenarios are numba-compiled floating
  # point, and a study is only comparable with another on the same scenario files
  # (scripts/proving_ground/README.md, "Reproducibility"). The check below asserts them.
  pins=(numpy==2.4.6 scipy==1.17.1 numba==0.68.1)
  packages=(ros-rclpy ros-std-msgs ros-diagnostic-msgs ros-rmw-fastrtps-cpp ros-rosgraph-msgs
            eclipse-zenoh rosbags mcap mcap-ros2-support websockets "${pins[@]}" pillow)
  check="import rclpy, std_msgs.msg, diagnostic_msgs.msg, rosgraph_msgs.msg, zenoh, rosbags, mcap, mcap_ros2, websockets, numpy, scipy, numba, PIL
from importlib.metadata import version
for pin in '${pins[*]}'.split():
    name, want = pin.split('==')
    assert version(name) == want, f'{name} {version(name)}, pinned {want}'"
fi
if [ -x "$venv/bin/python" ] && "$venv/bin/python" -c "$check" 2>/dev/null; then
  echo "venv $venv ready"
  exit 0
fi
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check "${packages[@]}"
"$venv/bin/python" -c "$check"
echo "venv $venv ready"
