#!/usr/bin/env bash
# The demo recordings of recordings/ (see recordings/README.md): scenarios/diagnose-demo.toml on
# the simulated bench with one or two effects switched on in [simulation.truth.effects], so
# concealed from the recording's bench.gyro_model. Small by default (gyro and table at 2 Hz,
# chamber at 0.5 Hz, ≈ 1 MB each); RATE_HZ=20 CHAMBER_HZ=20 OUT=dir writes full-rate ones;
# BENCH=path uses that bench binary instead of building one.
set -euo pipefail
cd "$(dirname "$0")/.."
rate="${RATE_HZ:-2}"
chamber="${CHAMBER_HZ:-0.5}"
out="${OUT:-recordings}"
mkdir -p "$out"
bench="${BENCH:-}"
if [ -z "$bench" ]; then
  cargo build --release -p bench --quiet
  bench=./target/release/bench
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
variant() { # name, effects TOML (may be empty), seed
  local f="$tmp/$1.toml"
  sed -e "s/^sample_rate = \"20 Hz\"/sample_rate = \"$rate Hz\"/" \
      -e "s/^\[table\]$/[table]\npoll_rate = \"$rate Hz\"/" scenarios/diagnose-demo.toml > "$f"
  printf '\n[chamber]\npoll_rate = "%s Hz"\n' "$chamber" >> "$f"
  if [ -n "$2" ]; then printf '\n[simulation.truth.effects]\n%s\n' "$2" >> "$f"; fi
  "$bench" run "$f" --seed "$3" --quiet --force --out "$out/$1.mcap"
}
variant demo-null "" 1
variant demo-once-per-revolution 'once_per_revolution = { amplitude_rad_s = 8e-8, phase_rad = 0.5 }' 2
variant demo-warm-up-and-step $'warm_up = { amplitude_rad_s = 3e-7, time_constant_s = 600 }\nbias_step = { time_s = 3000, step_rad_s = 1e-7 }' 1
ls -l "$out"/demo-*.mcap
