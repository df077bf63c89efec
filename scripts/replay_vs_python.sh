#!/usr/bin/env bash
# Read rate of a recording: bench's reader and the bare `mcap` crate (release build) against the
# Python `mcap` reader (pip install mcap zstandard lz4), on the same file.
#
#   bash scripts/replay_vs_python.sh [REC.mcap]   # default: records scenarios/seed.toml first
set -euo pipefail
cd "$(dirname "$0")/.."
rec="${1:-}"
if [[ -z "$rec" ]]; then
  rec="$(mktemp -d)/seed.mcap"
  cargo run --release -q -p bench -- run scenarios/seed.toml --out "$rec" --quiet >/dev/null
fi
cargo run --release -q -p bench --example read_rate -- "$rec" 5
python3 - "$rec" <<'PY'
import json, sys, time
from mcap.reader import make_reader

path = sys.argv[1]

def best(f, repeats=3):
    b, n = float("inf"), 0
    for _ in range(repeats):
        t = time.perf_counter()
        n = f()
        b = min(b, time.perf_counter() - t)
    return n, b

def raw():
    with open(path, "rb") as f:
        return sum(1 for _ in make_reader(f).iter_messages())

def decoded():
    n = 0
    with open(path, "rb") as f:
        for _schema, _channel, message in make_reader(f).iter_messages():
            json.loads(message.data)
            n += 1
    return n

for name, f in [("python mcap iter_messages (raw)", raw),
                ("python mcap iter_messages + json.loads", decoded)]:
    n, s = best(f)
    print(f"{name:<42} {n:>9} msgs {s:>8.3} s {n / s:>12.0f} msgs/s")
PY
