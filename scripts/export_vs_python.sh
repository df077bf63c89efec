#!/usr/bin/env bash
# Export speed (issue 29): `bench export` to CSV and to Parquet against the Python reference
# (`scripts/export_reference.py`: the `mcap` package's reader and `json.loads` of every body),
# whole processes, on the same file, run in turn (CSV, Parquet, Python) REPEAT times; prints
# each run's wall and CPU seconds (GNU time) and the median ratios.
#
#   bash scripts/export_vs_python.sh [REC.mcap] [REPEAT]   # default: records thermal-short first
set -euo pipefail
cd "$(dirname "$0")/.."
rec="${1:-}"
repeat="${2:-3}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cargo build --release -q -p bench
bench=./target/release/bench
if [[ -z "$rec" ]]; then
  rec="$tmp/thermal-short.mcap"
  "$bench" run scenarios/thermal-short.toml --seed 1 --quiet --force --out "$rec" >/dev/null
fi
py="$(bash scripts/pyenv.sh)"
timed() { # name, command...: appends "name wall cpu" to $tmp/times
  local name=$1
  shift
  /usr/bin/time -f "$name %e %U %S" -a -o "$tmp/times" "$@" >/dev/null
}
for _ in $(seq "$repeat"); do
  timed csv "$bench" export "$rec" --format csv --out "$tmp/csv" -q
  timed parquet "$bench" export "$rec" --format parquet --out "$tmp/parquet" -q
  rm -rf "$tmp/csv" "$tmp/parquet"
  timed python "$py" scripts/export_reference.py "$rec"
done
"$py" - "$tmp/times" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    name, wall, user, sys_ = line.split()
    runs.setdefault(name, []).append((float(wall), float(user) + float(sys_)))
med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in runs.items()}
for k, (w, c) in med.items():
    print(f"{k:<8} median wall {w:7.2f} s  CPU {c:7.2f} s  ({len(runs[k])} runs)")
pw, pc = med["python"]
for k in ("csv", "parquet"):
    w, c = med[k]
    print(f"python / {k}: {pw / w:.1f}x wall, {pc / c:.1f}x CPU")
PY
