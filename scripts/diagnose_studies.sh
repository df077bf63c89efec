#!/usr/bin/env bash
# The false-discovery and recovery studies of docs/diagnose.md ("Figures"): `bench monte-carlo
# --diagnose` on scenarios/diagnose-demo.toml with each concealed truth in turn (release build).
#
#   bash scripts/diagnose_studies.sh [OUT_DIR]   # one summary file per study in OUT_DIR
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-$(mktemp -d)}"
mkdir -p "$out"
cargo build --release -q -p bench
bench=target/release/bench
base=scenarios/diagnose-demo.toml

study() { # name seeds effects-toml [extra args]
  local name=$1 seeds=$2 effects=$3
  shift 3
  local s="$out/$name.toml"
  { cat "$base"; printf '\n[simulation.truth.effects]\n%s\n' "$effects"; } >"$s"
  "$bench" monte-carlo "$s" --diagnose --seeds "$seeds" "$@" >"$out/$name.txt" 2>&1
  echo "== $name"
  tail -n 12 "$out/$name.txt"
}

study null 50 ""
study parameters_only 50 "" --model scenarios/models/diagnose-demo-params-off.toml
study warm_up 20 "warm_up = { amplitude_rad_s = 2e-7, time_constant_s = 600 }"
study bias_step 20 "bias_step = { time_s = 3000, step_rad_s = 1e-7 }"
study temperature_quadratic 20 "temperature_quadratic = { coeff_rad_s_per_c2 = 4e-10 }"
study scale_factor_temperature 20 "scale_factor_temperature = { coeff_per_c = 1e-6 }"
study rate_squared 20 "rate_squared = { coeff_s_per_rad = 1e-2 }"
study time_offset 20 "time_offset = { offset_s = 2e-4 }"
study thermal_hysteresis 20 "thermal_hysteresis = { half_width_rad_s = 5e-8, threshold_c_s = 0.0016667 }"
study thermal_lag 20 "thermal_lag = { time_constant_s = 400 }"
study once_per_revolution 20 "once_per_revolution = { amplitude_rad_s = 3e-8, phase_rad = 0.5 }"
study periodic_bias 20 "periodic_bias = { amplitude_rad_s = 4e-8, period_s = 1320, phase_rad = 0.6 }"
study warm_up_and_bias_step 20 "warm_up = { amplitude_rad_s = 3e-7, time_constant_s = 600 }
bias_step = { time_s = 3000, step_rad_s = 1e-7 }"
study once_per_revolution_and_bias_step 20 "once_per_revolution = { amplitude_rad_s = 3e-8, phase_rad = 0.5 }
bias_step = { time_s = 3000, step_rad_s = 1e-7 }"
echo "summaries in $out"
