#!/usr/bin/env bash
# Create (or reuse) the tests' Python environment in target/pyenv with the pinned packages of
# scripts/requirements.txt, and print its interpreter's path. Idempotent: reinstalls only when
# requirements.txt changed.
set -euo pipefail
cd "$(dirname "$0")/.."
env_dir=target/pyenv
req=scripts/requirements.txt
stamp="$env_dir/.requirements"
if [ ! -x "$env_dir/bin/python3" ] || ! cmp -s "$req" "$stamp"; then
    echo "== python: installing pinned packages into $env_dir" >&2
    mkdir -p target
    python3 -m venv "$env_dir" >&2
    "$env_dir/bin/python3" -m pip install --quiet --disable-pip-version-check -r "$req" >&2
    cp "$req" "$stamp"
fi
echo "$PWD/$env_dir/bin/python3"
