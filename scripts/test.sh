#!/usr/bin/env bash
# The README's test command: every test of the workspace. Installs the pinned Python packages
# the tests use as independent peers and fixture writers (scripts/pyenv.sh, into target/pyenv)
# and runs `cargo test` with BENCH_PYTHON pointing at that interpreter.
set -euo pipefail
cd "$(dirname "$0")/.."
BENCH_PYTHON="$(bash scripts/pyenv.sh)"
export BENCH_PYTHON
cargo test --workspace --locked "$@"
