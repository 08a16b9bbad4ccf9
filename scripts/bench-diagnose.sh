#!/usr/bin/env bash
# Wall time of `mrtwin diagnose` on 20 000-sample records, with the bootstrap calibration
# (default selector) next to the first version's rules (no calibration) in the same run.
# Records: the Dyke broadband real record (20 032 samples) and proving-ground seed 0
# (20 000 samples, three hidden effects). Best of N runs each (default 3).
#   bash scripts/bench-diagnose.sh [N]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
bash scripts/setup-venv.sh >/dev/null
cargo build --release -p mrtwin >/dev/null 2>&1
bin=target/release/mrtwin
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
.venv/bin/python scripts/proving_ground/generate.py --seed 0 --out "$tmp/pg0.csv" >/dev/null
records=("../shared/data/real/dyke-nees/ransim_u.csv" "$tmp/pg0.csv")
printf '| record | samples | selector | best wall time of %s (s) | CPU (s) |\n|---|---|---|---|---|\n' "$runs"
for rec in "${records[@]}"; do
  n=$(($(wc -l <"$rec") - 1))
  for sel in rules calibrated; do
    best=""; cpu=""
    for _ in $(seq "$runs"); do
      out=$( { /usr/bin/time -f '%e %U %S' "$bin" diagnose "$rec" --selector "$sel" \
               --json "$tmp/out.json" --report /dev/null >/dev/null; } 2>&1 | tail -1)
      read -r wall user sys <<<"$out"
      if [ -z "$best" ] || awk "BEGIN{exit !($wall < $best)}"; then
        best=$wall; cpu=$(awk "BEGIN{print $user + $sys}")
      fi
    done
    printf '| %s | %s | %s | %s | %s |\n' "$(basename "$rec")" "$n" "$sel" "$best" "$cpu"
  done
done
