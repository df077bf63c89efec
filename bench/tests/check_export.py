"""Check `bench export --format parquet --merged` against the recording, independently.

Usage: check_export.py RECORDING.mcap EXPORT_DIR. Reads the recording with the `mcap` package
and the tables with pyarrow (both pinned in scripts/requirements.txt); exits non-zero with the
reason on the first disagreement and prints a JSON summary on success.
"""
import bisect
import json
import sys

import pyarrow as pa
import pyarrow.parquet as pq
from mcap.reader import make_reader

rec, out = sys.argv[1], sys.argv[2]

msgs = {}
with open(rec, "rb") as f:
    for _schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
        if channel.message_encoding == "json":
            msgs.setdefault(channel.topic, []).append((message.log_time, json.loads(message.data)))


def fail(why):
    sys.exit(f"check_export: {why}")


# Every table: a UTC nanosecond timestamp first, equal to the log time; units in the metadata.
UNITS = {
    "gyro_rate": {"rate": "rad/s", "temperature": "°C"},
    "table_state": {"angle": "rad", "rate": "rad/s", "rate_command": "rad/s"},
    "chamber_state": {"temperature": "°C", "setpoint": "°C"},
}
for name, units in UNITS.items():
    t = pq.read_table(f"{out}/{name}.parquet")
    field = t.schema.field("timestamp")
    if field.type != pa.timestamp("ns", tz="UTC") or t.schema.names[0] != "timestamp":
        fail(f"{name}: timestamp column is {field.type} at {t.schema.names.index('timestamp')}")
    if t.column("timestamp").cast(pa.int64()).to_pylist() != t.column("log_time_ns").to_pylist():
        fail(f"{name}: timestamp differs from log_time_ns")
    meta = {k.decode(): v.decode() for k, v in (t.schema.metadata or {}).items()}
    for col, unit in units.items():
        if meta.get(f"unit.{col}") != unit:
            fail(f"{name}: unit.{col} = {meta.get(f'unit.{col}')!r}, expected {unit!r}")
    if json.loads(meta["bench.units"]).get("rate" if "rate" in units else "temperature") is None:
        fail(f"{name}: bench.units {meta['bench.units']}")

m = pq.read_table(f"{out}/merged.parquet")
meta = {k.decode(): v.decode() for k, v in (m.schema.metadata or {}).items()}
for col, unit in [("gyro_rate", "rad/s"), ("table_rate", "rad/s"), ("table_angle", "rad"),
                  ("chamber_temperature", "°C"), ("bench_time_s", "s")]:
    if meta.get(f"unit.{col}") != unit:
        fail(f"merged: unit.{col} = {meta.get(f'unit.{col}')!r}")
if m.schema.field("timestamp").type != pa.timestamp("ns", tz="UTC"):
    fail(f"merged: timestamp is {m.schema.field('timestamp').type}")
rows = m.to_pylist()
gyro = msgs["/gyro/rate"]
if len(rows) != len(gyro):
    fail(f"merged has {len(rows)} rows, the recording {len(gyro)} gyro samples")

# As-of: the last reading logged at or before each gyro sample.
def asof(topic, t):
    times = [x[0] for x in msgs[topic]]
    k = bisect.bisect_right(times, t) - 1
    return msgs[topic][k] if k >= 0 else None

# Record windows from the step events: [start, end) of each step labelled record…
starts, windows = {}, []
for t, s in msgs["/bench/step"]:
    if s["event"] == "start" and s["label"].startswith("record"):
        starts[s["index"]] = (t, s["label"])
    elif s["event"] in ("end", "abort") and s["index"] in starts:
        a, label = starts.pop(s["index"])
        windows.append((a, t, label))

def window(t):
    """The record window's label, None (Parquet null) outside every window."""
    return next((label for a, b, label in windows if a <= t < b), None)

n = len(rows)
picks = sorted({0, 1, 2, 3, 7, n // 7, n // 3, n // 2 + 1, (2 * n) // 3, n - 1})
# Samples just inside and just outside the first record window too.
a0, b0, _ = windows[0]
gt = [t for t, _ in gyro]
picks += [bisect.bisect_left(gt, a0), bisect.bisect_left(gt, a0) - 1, bisect.bisect_left(gt, b0)]
held = 0
for i in picks:
    t, g = gyro[i]
    r = rows[i]
    if r["log_time_ns"] != t or r["gyro_rate"] != g["rate"]:
        fail(f"row {i}: gyro sample differs: {r} vs {t} {g}")
    for topic, prefix, fields in [("/table/state", "table", ["angle", "rate", "rate_command"]),
                                  ("/chamber/state", "chamber", ["temperature", "setpoint"])]:
        want = asof(topic, t)
        if want is None:
            if r[f"{prefix}_log_time_ns"] is not None:
                fail(f"row {i}: {prefix} reading before the first one")
            continue
        if r[f"{prefix}_log_time_ns"] != want[0]:
            fail(f"row {i}: {prefix} reading of {r[f'{prefix}_log_time_ns']}, as-of {want[0]}")
        held += want[0] < t
        for fld in fields:
            if r[f"{prefix}_{fld}"] != want[1][fld]:
                fail(f"row {i}: {prefix}_{fld} = {r[f'{prefix}_{fld}']} vs {want[1][fld]}")
    if r["record_window"] != window(t):
        fail(f"row {i}: record_window {r['record_window']!r} vs {window(t)!r}")
# Never a reading from the future, anywhere.
for r in rows:
    for p in ("table", "chamber"):
        if r[f"{p}_log_time_ns"] is not None and r[f"{p}_log_time_ns"] > r["log_time_ns"]:
            fail(f"a {p} reading from after its gyro sample: {r}")
labelled = sum(1 for r in rows if r["record_window"])
print(json.dumps({"rows": n, "columns": m.num_columns, "checked": len(picks),
                  "held_readings": held, "in_record_windows": labelled,
                  "windows": len(windows), "names": m.schema.names}))
