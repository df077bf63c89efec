#!/usr/bin/env bash
# Speed and memory figures of simulated runs (issue 2): bench time / wall time and peak RSS for
# the seed (≈1 h of bench time) and the full-range calibration (≈13.7 h), three runs each.
# Memory flat in run length shows as equal peak RSS for both.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p bench --quiet
out=$(mktemp -d)
for s in seed thermal-full; do
  for seed in 1 2 3; do
    ./target/release/bench run "scenarios/$s.toml" --seed "$seed" --quiet --force --out "$out/$s-$seed.mcap"
  done
done
rm -rf "$out"
# Recording overhead against the bare mcap writer:
#   cargo bench -p bench --bench record
