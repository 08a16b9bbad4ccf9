#!/usr/bin/env bash
# Fresh release build of the default `mrtwin` binary: wall time and resolved crate count,
# for a reference commit and for the working tree, one after the other in the same
# invocation, each in its own empty target directory (nothing shared, nothing cached
# but the downloaded sources).
#
#   bash scripts/bench-build.sh [REFERENCE_COMMIT]     (default: 677152a, before issue 11)
#
# WORK_TARGET=DIR keeps the working tree's fresh target directory there afterwards.
#
# Crate count: packages in the normal dependency graph of `mrtwin` with default features,
# from `cargo tree -e normal` (the method that gives the issue's 448 for the reference).
set -euo pipefail
cd "$(dirname "$0")/.."
ref=${1:-677152a}
work=$(mktemp -d)
trap 'git worktree remove --force "$work/ref" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
git worktree add --detach "$work/ref" "$ref" >/dev/null

count() { # $1: repository dir
  (cd "$1" && cargo tree -p mrtwin -e normal --prefix none 2>/dev/null |
    sed 's/ (\*)$//' | sort -u | wc -l)
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
  if [ "$side" = ref ]; then
    dir="$work/ref"; label="reference $ref"; target="$work/target-ref"
  else
    dir="$PWD"; label="working tree $(git rev-parse --short HEAD)"; target="${WORK_TARGET:-$work/target-work}"
    rm -rf "$target"
  fi
  n=$(count "$dir")
  s=$(build "$dir" "$target")
  printf '%-28s %8s %12.0f\n' "$label" "$n" "$s"
done
