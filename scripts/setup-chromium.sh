#!/usr/bin/env bash
# Headless Chromium from the Debian packages, for the test that renders
# `mrtwin diagnose --html` and checks its screenshot (cli/tests/diagnose.rs).
# Idempotent: does nothing when a chromium is already on PATH.
set -euo pipefail
for b in chromium chromium-browser; do
  if command -v "$b" >/dev/null; then
    echo "chromium ready: $(command -v "$b")"
    exit 0
  fi
done
sudo=()
if [ "$(id -u)" -ne 0 ]; then
  sudo=(sudo -n)
fi
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get install -y -q chromium >/dev/null 2>&1 || {
  "${sudo[@]}" apt-get update -q >/dev/null
  "${sudo[@]}" apt-get install -y -q chromium >/dev/null
}
echo "chromium ready: $(command -v chromium)"
