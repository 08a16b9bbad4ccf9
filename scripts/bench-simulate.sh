#!/usr/bin/env bash
# Time `mrtwin simulate` on a 30 s, 1 kHz, 9-segment recording (3 frequencies × 3 currents,
# 3.333 s each) of the compressible two-chamber model, beside the incompressible model as
# the reference, in the same invocation. Usage: bash scripts/bench-simulate.sh [REPEATS]
set -euo pipefail
cd "$(dirname "$0")/.."
repeats=${1:-5}
cargo build -q --release -p mrtwin
bin=target/release/mrtwin
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
common=(simulate --model two-chamber --frequency 1.66,3.33,5 --current 0.5,1,2
        --duration 3.333333 --rate 1000 --noise 0.01)
run() { # label, extra args...
  local label=$1; shift
  local best=1e9
  for _ in $(seq "$repeats"); do
    local t0 t1
    t0=$(date +%s.%N)
    "$bin" "${common[@]}" "$@" --out "$out/x.csv" 2>/dev/null
    t1=$(date +%s.%N)
    best=$(echo "$t1 $t0 $best" | awk '{d = $1 - $2; print (d < $3 ? d : $3)}')
  done
  printf '%-58s best of %s: %6.1f ms (%s samples)\n' "$label" "$repeats" "$(echo "$best" | awk '{print $1 * 1000}')" "$(($(wc -l < "$out/x.csv") - 1))"
}
run "reference: two-chamber incompressible (--effects none)" --effects none
run "two-chamber paper model (compressibility + gas)"
run "two-chamber all effects, Bingham"            --effects all
run "two-chamber all effects, Bodner-Partom"      --effects all --fluid bodner-partom --params launch-config/examples/stand.yaml
