#!/usr/bin/env bash
# The README's test command: every test of the workspace. Installs nothing beyond cargo's own
# dependency fetch.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test --workspace --locked "$@"
