#!/usr/bin/env bash
# Run every cargo-fuzz target of fuzz/ for a while, at the lowest CPU priority, and print a
# table: target, seconds, executions, findings (crash-/timeout-/oom- files written to
# fuzz/artifacts/<target>/ by this run). Installs cargo-fuzz if missing; needs a nightly toolchain.
#
#   bash scripts/fuzz.sh                 # every target, 300 s each
#   SECONDS_EACH=60 bash scripts/fuzz.sh scenario recover
#   JOBS=2 bash scripts/fuzz.sh          # two targets at a time
#   FUZZ_ARGS="-fork=1 -ignore_crashes=1" bash scripts/fuzz.sh recording   # go on past a known crash
#
# Corpora are fuzz/corpus/<target>/ (committed, minimised with `cargo fuzz cmin`); new inputs a
# run finds are added there: minimise again before committing them
# (`cargo +nightly fuzz cmin -O -a -s none TARGET`). Not part of CI (too long); the targets'
# build is (scripts/test.sh does not build them: see docs/robustness.md).
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH="${SECONDS_EACH:-300}"
JOBS="${JOBS:-1}"
# Release, with debug assertions and overflow checks; no sanitizer (the code is safe Rust:
# ASan finds nothing there a panic would not, and costs 2-3x the executions).
FLAGS=(-O -a -s none)

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "== installing cargo-fuzz" >&2
    cargo install cargo-fuzz --locked
fi

cd fuzz
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(cargo +nightly fuzz list)
fi
echo "== building ${#targets[@]} targets" >&2
nice -n 19 cargo +nightly fuzz build "${FLAGS[@]}" >&2

logs="$(mktemp -d)"
run_one() {
    local t="$1"
    mkdir -p "corpus/$t" "artifacts/$t"
    # An empty corpus starts from the seeds of fuzz/seed_corpora.py, if written.
    if [ -d "seeds/$t" ] && [ -z "$(ls -A "corpus/$t")" ]; then
        cp "seeds/$t"/* "corpus/$t"/
    fi
    local before
    before=$(find "artifacts/$t" -type f | wc -l)
    # -timeout: one input taking over 10 s is a hang; -rss_limit_mb: over 2 GB is an OOM.
    nice -n 19 cargo +nightly fuzz run "${FLAGS[@]}" "$t" "corpus/$t" -- \
        -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
        ${FUZZ_ARGS:-} \
        >"$logs/$t.log" 2>&1 || true
    local execs after
    execs=$(grep -m1 'stat::number_of_executed_units' "$logs/$t.log" | awk '{print $2}' || true)
    if [ -z "$execs" ]; then # -fork mode prints no final stats: its last progress line
        execs=$(grep -o '^#[0-9]*' "$logs/$t.log" | tail -n 1 | tr -d '#' || true)
    fi
    after=$(find "artifacts/$t" -type f | wc -l)
    printf '%s %s %s %s\n' "$t" "$SECONDS_EACH" "${execs:-?}" "$((after - before))" >"$logs/$t.row"
}
running=0
for t in "${targets[@]}"; do
    run_one "$t" &
    running=$((running + 1))
    if [ "$running" -ge "$JOBS" ]; then
        wait -n
        running=$((running - 1))
    fi
done
wait

printf '%-18s %8s %14s %9s\n' target seconds execs findings
total=0
for t in "${targets[@]}"; do
    read -r name secs execs found <"$logs/$t.row"
    printf '%-18s %8s %14s %9s\n' "$name" "$secs" "$execs" "$found"
    total=$((total + found))
done
echo "logs: $logs"
if [ "$total" -gt 0 ]; then
    echo "$total finding(s): see fuzz/artifacts/<target>/ and the logs" >&2
    exit 1
fi
