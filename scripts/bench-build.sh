#!/usr/bin/env bash
# Fresh release build of the default `mrtwin` binary: wall time and resolved crate count,
# for a reference commit and for the working tree, one after the other in the same
# invocation, each in its own empty target directory (nothing shared, nothing cached
# but the downloaded sources).
#
#   bash scripts/bench-build.sh [REFERENCE_COMMIT]     (default: 677152a, before issue 11)
#
# Crate count: packages in the dependency graph of `mrtwin` with default features, normal
# and build dependencies (what a release build compiles), from `cargo tree`.
set -euo pipefail
cd "$(dirname "$0")/.."
ref=${1:-677152a}
work=$(mktemp -d)
trap 'git worktree remove --force "$work/ref" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
git worktree add --detach "$work/ref" "$ref" >/dev/null

count() { # $1: repository dir
  (cd "$1" && cargo tree -p mrtwin -e normal,build --prefix none --format '{p}' 2>/dev/null |
    sed 's/ (.*//; s/ (\*)//' | sort -u | wc -l)
}
build() { # $1: repository dir, $2: target dir; prints seconds
  local t0 t1
  t0=$(date +%s.%N)
  (cd "$1" && CARGO_TARGET_DIR="$2" cargo build --release -p mrtwin -q)
  t1=$(date +%s.%N)
  echo "$t1 - $t0" | bc
}

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
printf '%-28s %8s %12s\n' "tree" "crates" "build [s]"
for side in ref work; do
  if [ "$side" = ref ]; then dir="$work/ref"; label="reference $ref"; else dir="$PWD"; label="working tree $(git rev-parse --short HEAD)"; fi
  n=$(count "$dir")
  s=$(build "$dir" "$work/target-$side")
  printf '%-28s %8s %12.0f\n' "$label" "$n" "$s"
done
