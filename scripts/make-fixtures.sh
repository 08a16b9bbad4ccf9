#!/usr/bin/env bash
# Regenerates the bag fixtures in tests/fixtures/bags (see docs/bags.md, "Fixtures"):
# a simulated two-chamber recording through `mrtwin simulate`, and the first 3 s of a
# real UTFSM recording (needs ../shared/data/real/maurel-utfsm) through bridge::bag.
set -euo pipefail
cd "$(dirname "$0")/.."
out=tests/fixtures/bags
mkdir -p "$out"
rm -rf "$out/simulated-two-chamber"
cargo run --release -q -p mrtwin -- simulate --model two-chamber --frequency 2 \
  --current 0.5,1 --duration 1 --rate 1000 --noise 0.01 --seed 7 --name sim \
  --out "$out/simulated-two-chamber"
cargo test --release -q -p bridge --test bag -- --ignored --exact regenerate_real_fixture
du -sh "$out"/*

# Golden replay outputs (cli/tests/replay.rs compares fresh replays against them).
# Regenerate only on purpose, when the twin's physics or defaults change, and say why.
mkdir -p tests/fixtures/golden
for bag in simulated-two-chamber utfsm-10mm1Hz1A; do
  cargo run --release -q -p mrtwin -- replay "$out/$bag" --out "tests/fixtures/golden/$bag.replay.csv"
done
du -sh tests/fixtures/golden/*
