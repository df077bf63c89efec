#!/usr/bin/env bash
# The README's test command: every test of the workspace. Installs the pinned Python packages
# the tests use as independent peers and fixture writers (scripts/pyenv.sh, into target/pyenv)
# and runs the tests with BENCH_PYTHON pointing at that interpreter; installs the pinned
# headless Chromium the report rendering test uses (scripts/browser.sh) and passes its path as
# BENCH_CHROMIUM (empty, and that test skipping with the reason, when it cannot be installed).
#
# The two installs (network and disk, ~45 s on a clean machine) run while the tests compile.
# With cargo-nextest installed the tests run in one pool over every test binary, longest first
# (.config/nextest.toml), two threads more than the processors, then the doc tests; otherwise
# `cargo test`, a binary at a time.
# Arguments go to the test runner: `-- NAME` runs the tests whose names hold NAME under either
# (the doc tests, a few seconds, always run whole); BENCH_TEST_RUNNER=cargo forces cargo test.
set -euo pipefail
cd "$(dirname "$0")/.."
got="$(mktemp -d)"
trap 'rm -rf "$got"' EXIT
bash scripts/pyenv.sh >"$got/python" &
python_pid=$!
bash scripts/browser.sh >"$got/chromium" &
browser_pid=$!
nextest=false
if [ "${BENCH_TEST_RUNNER:-}" != cargo ] && cargo nextest --version >/dev/null 2>&1; then
    nextest=true
fi
# The build's own arguments: those before `--` (the rest are the test binaries').
build_args=()
for a in "$@"; do
    [ "$a" = "--" ] && break
    build_args+=("$a")
done
if $nextest; then
    cargo nextest run --workspace --locked --no-run "${build_args[@]}"
else
    cargo test --workspace --locked --no-run "${build_args[@]}"
fi
wait "$python_pid" || { echo "== python: installing the test environment failed" >&2; exit 1; }
wait "$browser_pid" || true # never fails: prints nothing when chromium cannot be installed
BENCH_PYTHON="$(cat "$got/python")"
export BENCH_PYTHON
BENCH_CHROMIUM="$(cat "$got/chromium")"
export BENCH_CHROMIUM
if $nextest; then
    # Two test threads more than the machine's processors (unless NEXTEST_TEST_THREADS says
    # otherwise): a fifth of the suite's time is spent waiting — paced bench clocks, child
    # processes, sockets — and with one thread per processor that time left a core idle. On this
    # 2-core machine (2026-12-01, one call each, fixtures cached): 2 threads 356 s wall at 78 %
    # of both cores, 3 threads 312 s, 4 threads 284 s at 88 %, every test passing in each.
    NEXTEST_TEST_THREADS="${NEXTEST_TEST_THREADS:-$(($(nproc) + 2))}"
    export NEXTEST_TEST_THREADS
    status=0
    cargo nextest run --workspace --locked --no-fail-fast "$@" || status=$?
    cargo test --workspace --locked --doc || status=$?
    exit "$status"
fi
cargo test --workspace --locked --no-fail-fast "$@"
