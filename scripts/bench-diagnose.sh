#!/usr/bin/env bash
# Wall time of `mrtwin diagnose` on 20 000-sample records, with the bootstrap calibration
# (default selector) next to the first version's rules (no calibration) in the same run.
# Records: the Dyke broadband real record (20 032 samples), proving-ground seed 0
# (20 000 samples, three hidden effects) and UTFSM 5mm3Hz (its five currents concatenated
# as scripts/diagnose-real.py does, 21 097 samples; the slowest real record). Best of N
# runs each (default 3). With REF_BIN set, that binary (e.g. an older build) is timed
# with the calibrated selector in the same run, as one more row per record; with BIN set,
# that binary is timed instead of a fresh build of target/release/mrtwin.
#   bash scripts/bench-diagnose.sh [N]
#   REF_BIN=/tmp/mrtwin-old bash scripts/bench-diagnose.sh 1
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
bash scripts/setup-venv.sh >/dev/null
if [ -n "${BIN:-}" ]; then
  bin=$BIN
else
  cargo build --release -p mrtwin >/dev/null 2>&1
  bin=target/release/mrtwin
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
.venv/bin/python scripts/proving_ground/generate.py --seed 0 --out "$tmp/pg0.csv" >/dev/null
python3 -c "import importlib.util as u; s = u.spec_from_file_location('r', 'scripts/diagnose-real.py'); \
m = u.module_from_spec(s); s.loader.exec_module(m); m.utfsm_csv('5mm3Hz', '$tmp/utfsm-5mm3Hz.csv')"
records=("../shared/data/real/dyke-nees/ransim_u.csv" "$tmp/pg0.csv" "$tmp/utfsm-5mm3Hz.csv")
printf '| record | samples | selector | best wall time of %s (s) | CPU (s) |\n|---|---|---|---|---|\n' "$runs"
for rec in "${records[@]}"; do
  n=$(($(wc -l <"$rec") - 1))
  runs_of=("$bin rules" "$bin calibrated")
  [ -n "${REF_BIN:-}" ] && runs_of+=("$REF_BIN calibrated")
  for run_of in "${runs_of[@]}"; do
    read -r b sel <<<"$run_of"
    best=""; cpu=""
    for _ in $(seq "$runs"); do
      out=$( { /usr/bin/time -f '%e %U %S' "$b" diagnose "$rec" --selector "$sel" \
               --json "$tmp/out.json" --report /dev/null >/dev/null; } 2>&1 | tail -1)
      read -r wall user sys <<<"$out"
      if [ -z "$best" ] || awk "BEGIN{exit !($wall < $best)}"; then
        best=$wall; cpu=$(awk "BEGIN{print $user + $sys}")
      fi
    done
    label=$sel
    [ "$b" != "$bin" ] && label="$sel ($(basename "$b"))"
    printf '| %s | %s | %s | %s | %s |\n' "$(basename "$rec")" "$n" "$label" "$best" "$cpu"
  done
done
