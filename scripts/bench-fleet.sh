#!/usr/bin/env bash
# Issue 16: how many 1 kHz dampers `mrtwin fleet` keeps in step on this machine, and at what
# CPU and latency. One run per fleet size, one after the other in this invocation (the
# single damper is the reference row), nothing else should be running.
#
#   bash scripts/bench-fleet.sh [SIZES...]      # default: 1 10 25 50 75 100
#
# Prints a Markdown table: dampers, dampers without loss (sent = stepped by its twin =
# received by the central monitor), samples lost, CPU (% of all cores, whole process:
# stands, twins, monitor and zenoh), sample-to-monitor latency p50 / p99 / max, and the
# stands' worst lateness behind their schedule. Raw JSON per size in target/bench-fleet/.
set -euo pipefail
cd "$(dirname "$0")/.."
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(1 10 25 50 75 100)
duration=${FLEET_DURATION:-10}
cargo build --release -p mrtwin --quiet
out=target/bench-fleet
mkdir -p "$out"
echo "| dampers | without loss | samples lost | CPU (% of $(nproc) cores) | latency p50 / p99 / max (ms) | stand lateness max (ms) |"
echo "|---:|---:|---:|---:|---|---:|"
for n in "${sizes[@]}"; do
  target/release/mrtwin --log-level warn fleet --dampers "$n" --duration "$duration" \
    --key-prefix "bench_fleet_$$" --json "$out/fleet-$n.json" > /dev/null
  python3 - "$out/fleet-$n.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
lost = sum(x["sent"] - x["received"] for x in d["dampers"])
l = d["latency_ms"]
print(f"| {len(d['dampers'])} | {d['dampers_without_loss']} | {lost} | {d['cpu_percent']:.0f} | "
      f"{l['p50']:.2f} / {l['p99']:.2f} / {l['max']:.1f} | {d['stand_max_lateness_ms']:.2f} |")
PY
done
