#!/usr/bin/env bash
# The sim-vs-real workflow on every lab-writer preset (issue 26, fix 1): for each preset's short
# file REAL, `bench model REAL -o m.toml`, `bench run` of a short scenario with
# `--gyro-model m.toml` into SIM, then `bench diagnose REAL` and `bench diagnose REAL --model SIM`:
# the accepted names must be the same (the simulated table's ripple and clocks are never
# applied to the real table). Prints one line per preset and exits 1 on any difference.
#   bash scripts/lab_model_elsewhere.sh [BENCH] [SEED]
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH=${1:-target/release/bench}
SEED=${2:-1}
PY="$(bash scripts/pyenv.sh)"
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
printf '[scenario]\nname = "short"\n[site]\nlatitude_deg = 59.94\n\n[[step]]\nwait = "10 s"\n' > "$W/short.toml"
names() { "$PY" -c 'import json,sys; print(",".join(sorted(f["effect"] for f in json.load(open(sys.argv[1]))["findings"])) or "-")' "$1"; }
fail=0
for p in lab-null lab-nosensor $("$PY" tests/fixtures/lab/labwriter.py --list-presets | awk '{print $1}' | grep '^effect-'); do
  "$PY" tests/fixtures/lab/labwriter.py "$W/$p.mcap" --preset "short-$p" --seed "$SEED" > /dev/null
  "$BENCH" model "$W/$p.mcap" -o "$W/$p.toml" > /dev/null
  "$BENCH" run "$W/short.toml" --gyro-model "$W/$p.toml" --out "$W/$p-sim.mcap" --force -q > /dev/null
  "$BENCH" diagnose "$W/$p.mcap" -o "$W/$p-own" --json "$W/$p-own.json" --no-report -q > /dev/null || true
  "$BENCH" diagnose "$W/$p.mcap" --model "$W/$p-sim.mcap" -o "$W/$p-sim" --json "$W/$p-sim.json" --no-report -q > /dev/null || true
  own=$(names "$W/$p-own.json"); sim=$(names "$W/$p-sim.json")
  if [ "$own" = "$sim" ]; then echo "same       $p: $own"; else echo "DIFFERENT  $p: own $own, --model sim $sim"; fail=1; fi
done
exit $fail
