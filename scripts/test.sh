#!/usr/bin/env bash
# The README's test command: every test of the workspace. Installs the pinned Python packages
# the tests use as independent peers and fixture writers (scripts/pyenv.sh, into target/pyenv)
# and runs `cargo test` with BENCH_PYTHON pointing at that interpreter; installs the pinned
# headless Chromium the report rendering test uses (scripts/browser.sh) and passes its path as
# BENCH_CHROMIUM (empty, and that test skipping with the reason, when it cannot be installed).
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH_PYTHON="$(bash scripts/pyenv.sh)"
export BENCH_PYTHON
BENCH_CHROMIUM="$(bash scripts/browser.sh)"
export BENCH_CHROMIUM
cargo test --workspace --locked --no-fail-fast "$@"
