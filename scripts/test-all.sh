#!/usr/bin/env bash
# The whole mrtwin test suite, from a fresh clone with ../shared beside it.
# Sets up everything it needs itself; no ROS install, no external server.
set -euo pipefail
cd "$(dirname "$0")/.."

if [ ! -d ../shared/data/real ]; then
  echo "error: ../shared/data/real not found beside the repository (the real recordings the tests read)" >&2
  exit 1
fi

echo "== cargo fmt --check"
cargo fmt --all -- --check

echo "== cargo clippy -D warnings"
cargo clippy --workspace --all-targets --release -- -D warnings

echo "== cargo test (release: the physics tests integrate long records)"
cargo test --workspace --release
