#!/usr/bin/env python3
"""Feed the `bench` binary broken inputs and count how it fails.

Generates broken scenarios, bench configs and model files (TOML) and corrupted recordings
(MCAP, from recordings/), runs the verb that reads each one under a timeout, and classifies
every run:

  panic      exit code 101, "panicked" on stderr, or killed by a signal (stack overflow, abort)
  hang       still running after the timeout (--timeout, default 60 s), killed
  unlocated  a failure (exit 1 or 3) whose message does not say where the input is wrong:
               TOML (scenario, bench config, model file): no `FILE:LINE:COLUMN:` naming the
                 broken file (FILE as given on the command line); a model file that starts
                 with MCAP's magic is read as a recording and judged as one;
               recording: the message does not name the file, or names no place in it: none of
                 `byte N`, `message sequence N`, a channel (`/gyro/rate`, `/table/state`,
                 `/chamber/state`, `/bench/step`, `/log`, `channel id N`) or a metadata record
                 (`bench.site`, `bench.gyro_model`, ...)
  error      a failure with such a location (the expected outcome)
  accepted   exit 0, or a verdict exit code of calibrate/diagnose (5..9): the input was usable
             (a truncated recording is read up to its break; some mutations leave it valid)

Prints one line per run with --verbose, a table of counts per input kind, and exits 1 if any
run panicked, hung or failed without a location.

Usage: BENCH_BIN=target/debug/bench target/pyenv/bin/python3 scripts/bad_inputs.py [--quick]
(needs the `mcap` package of scripts/requirements.txt: `bash scripts/pyenv.sh`).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# ------------------------------------------------------------------------------ scenarios

SCENARIO = """\
[scenario]
name = "bad"

[site]
latitude_deg = 45.0
axis = "up"

[gyro]
sample_rate = "20 Hz"

[table]
accel = "1 °/s²"

[safe]
decel = "10 °/s²"
temperature = "20 °C"

[[step]]
label = "to 30C"
chamber = "30 °C"
ramp = "2 °C/min"

[[step]]
label = "soak 30C"
wait_temperature = "30 °C"
source = "gyro"
band = "0.5 °C"
hold = "5 min"
timeout = "2 h"

[[step]]
for.dir = ["cw", "ccw"]

  [[step.do]]
  label = "spin {dir}"
  spin = "10 °/min"
  direction = "{dir}"

  [[step.do]]
  label = "record {dir} 30C"
  record = "5 min"

[[step]]
label = "stop"
stop = "table"
"""


def sub(base: str, old: str, new: str) -> str:
    assert old in base, old
    return base.replace(old, new, 1)


def scenarios() -> list[tuple[str, bytes]]:
    s = SCENARIO
    cases: list[tuple[str, str | bytes]] = [
        ("empty file", ""),
        ("comment only", "# nothing\n"),
        ("unclosed string", sub(s, 'name = "bad"', 'name = "bad')),
        ("unclosed table header", sub(s, "[site]", "[site")),
        ("duplicate key", sub(s, "axis = \"up\"", "axis = \"up\"\naxis = \"down\"")),
        ("duplicate table", s + "\n[gyro]\nsample_rate = \"1 Hz\"\n"),
        ("unknown section", s + "\n[turbo]\nboost = true\n"),
        ("unknown key in [gyro]", sub(s, 'sample_rate = "20 Hz"', 'sample_rate = "20 Hz"\nsampel = 1')),
        ("unknown key in a step", sub(s, 'stop = "table"', 'stop = "table"\nspeed = "fast"')),
        ("missing [scenario]", sub(s, '[scenario]\nname = "bad"\n', "")),
        ("empty name", sub(s, 'name = "bad"', 'name = ""')),
        ("name is a number", sub(s, 'name = "bad"', "name = 5")),
        ("latitude out of range", sub(s, "latitude_deg = 45.0", "latitude_deg = 95.0")),
        ("latitude is a string", sub(s, "latitude_deg = 45.0", 'latitude_deg = "north"')),
        ("latitude NaN", sub(s, "latitude_deg = 45.0", "latitude_deg = nan")),
        ("latitude 1e400", sub(s, "latitude_deg = 45.0", "latitude_deg = 1e400")),
        ("bad axis", sub(s, 'axis = "up"', 'axis = "sideways"')),
        ("sample rate not offered", sub(s, '"20 Hz"', '"33 Hz"')),
        ("sample rate bad unit", sub(s, '"20 Hz"', '"20 parsecs"')),
        ("sample rate negative", sub(s, '"20 Hz"', '"-20 Hz"')),
        ("sample rate no number", sub(s, '"20 Hz"', '"Hz"')),
        ("sample rate is a table", sub(s, 'sample_rate = "20 Hz"', "sample_rate = { hz = 20 }")),
        ("accel zero", sub(s, 'accel = "1 °/s²"', 'accel = "0 °/s²"')),
        ("accel wrong dimension", sub(s, 'accel = "1 °/s²"', 'accel = "1 °C"')),
        ("safe temperature out of range", sub(s, 'temperature = "20 °C"', 'temperature = "1000 °C"')),
        ("chamber above range", sub(s, 'chamber = "30 °C"', 'chamber = "500 °C"')),
        ("chamber below absolute zero", sub(s, 'chamber = "30 °C"', 'chamber = "-300 °C"')),
        ("chamber wrong dimension", sub(s, 'chamber = "30 °C"', 'chamber = "30 m"')),
        ("ramp zero", sub(s, 'ramp = "2 °C/min"', 'ramp = "0 °C/min"')),
        ("ramp negative", sub(s, 'ramp = "2 °C/min"', 'ramp = "-2 °C/min"')),
        ("ramp too fast", sub(s, 'ramp = "2 °C/min"', 'ramp = "200 °C/min"')),
        ("band negative", sub(s, 'band = "0.5 °C"', 'band = "-0.5 °C"')),
        ("bad source", sub(s, 'source = "gyro"', 'source = "moon"')),
        ("hold bad duration", sub(s, 'hold = "5 min"', 'hold = "5 fortnights"')),
        ("timeout zero", sub(s, 'timeout = "2 h"', 'timeout = "0 s"')),
        ("timeout NaN", sub(s, 'timeout = "2 h"', 'timeout = "NaN s"')),
        ("spin too fast", sub(s, 'spin = "10 °/min"', 'spin = "1e9 °/s"')),
        ("spin infinite", sub(s, 'spin = "10 °/min"', 'spin = "inf °/s"')),
        ("bad direction", sub(s, 'direction = "{dir}"', 'direction = "up"')),
        ("unknown placeholder", sub(s, 'label = "spin {dir}"', 'label = "spin {speed}"')),
        ("unclosed placeholder", sub(s, 'label = "spin {dir}"', 'label = "spin {dir"')),
        ("record negative", sub(s, 'record = "5 min"', 'record = "-5 min"')),
        ("record empty", sub(s, 'record = "5 min"', 'record = ""')),
        ("record huge", sub(s, 'record = "5 min"', 'record = "1e300 h"')),
        ("step without action", sub(s, 'label = "stop"\nstop = "table"', 'label = "stop"')),
        ("step with two actions", sub(s, 'stop = "table"', 'stop = "table"\nwait = "1 min"')),
        ("bad stop", sub(s, 'stop = "table"', 'stop = "everything"')),
        ("empty for list", sub(s, 'for.dir = ["cw", "ccw"]', "for.dir = []")),
        ("for is a string", sub(s, 'for.dir = ["cw", "ccw"]', 'for.dir = "cw"')),
        ("for mixed types", sub(s, 'for.dir = ["cw", "ccw"]', 'for.dir = ["cw", 2]')),
        ("for without do", sub(s, "  [[step.do]]\n  label = \"spin {dir}\"", "  [[step.xx]]\n  label = \"spin {dir}\"")),
        ("step is a table", sub(s, '[[step]]\nlabel = "stop"', '[step]\nlabel = "stop"')),
        ("no steps", s.split("[[step]]")[0]),
        ("wait negative", sub(s, 'stop = "table"', 'stop = "table"\n\n[[step]]\nwait = "-1 min"')),
        ("deeply nested arrays", sub(s, 'name = "bad"', 'name = "bad"\nx = ' + "[" * 5000 + "]" * 5000)),
        ("deeply nested inline tables", sub(s, 'name = "bad"', 'name = "bad"\nx = ' + "{a=" * 5000 + "1" + "}" * 5000)),
        (
            "loop explosion",
            s
            + "\n[[step]]\nfor.a = [" + ",".join(str(i) for i in range(1000)) + "]\n"
            + "  [[step.do]]\n  for.b = [" + ",".join(str(i) for i in range(1000)) + "]\n"
            + "    [[step.do.do]]\n    for.c = [" + ",".join(str(i) for i in range(1000)) + "]\n"
            + '      [[step.do.do.do]]\n      label = "w {a} {b} {c}"\n      wait = "1 s"\n',
        ),
        ("invalid UTF-8", SCENARIO.encode().replace(b'"bad"', b'"b\xff\xfed"')),
        ("NUL byte", sub(s, 'name = "bad"', 'name = "b\0d"')),
        ("binary garbage", bytes(random.Random(1).randrange(256) for _ in range(2000))),
        ("CR only line ends", s.replace("\n", "\r")),
    ]
    for cut in (7, 40, 200, 333, len(s.encode()) - 3):
        cases.append((f"truncated at byte {cut}", s.encode()[:cut]))
    return [(n, c if isinstance(c, bytes) else c.encode()) for n, c in cases]


# ------------------------------------------------------------------------------ bench configs

CONFIG = """\
[site]
latitude_deg = 43.56
axis = "up"

[bench]
time_scale = 1.0
stale_after_s = 30

[limits]
table_max_rate_deg_s = 500.0
chamber_min_temp_c = -60.0
chamber_max_temp_c = 180.0
gyro_sample_rates_hz = [1.0, 20.0, 200.0]

[table]
dialect = "actidyn"
endpoint = { tcp = { addr = "127.0.0.1:62000" } }

[chamber]
endpoint = { serial = { path = "/dev/ttyUSB0", baud = 9600 } }
unit_id = 1
map = "watlow_f4t"

[gyro]
driver = "can"
transport = { kind = "slcan", serial = { path = "/dev/ttyACM0", baud = 115200 } }
sample_rate_hz = 20.0
"""

CUSTOM_MAP = """\
[chamber.map]
process_value = { register = 100, encoding = "int16" }
"""


def configs() -> list[tuple[str, bytes]]:
    c = CONFIG
    cases: list[tuple[str, str | bytes]] = [
        ("syntax error", sub(c, "[site]", "[site")),
        ("unknown section", c + "\n[laser]\npower = 1\n"),
        ("unknown key", sub(c, "unit_id = 1", "unit_id = 1\nunit = 2")),
        ("latitude out of range", sub(c, "latitude_deg = 43.56", "latitude_deg = 200.0")),
        ("latitude is a string", sub(c, "latitude_deg = 43.56", 'latitude_deg = "43N"')),
        ("bad axis", sub(c, 'axis = "up"', 'axis = "left"')),
        ("time scale zero", sub(c, "time_scale = 1.0", "time_scale = 0.0")),
        ("time scale NaN", sub(c, "time_scale = 1.0", "time_scale = nan")),
        ("stale_after negative", sub(c, "stale_after_s = 30", "stale_after_s = -30")),
        ("max errors negative", sub(c, "stale_after_s = 30", "stale_after_s = 30\nmax_consecutive_errors = -1")),
        ("limit negative", sub(c, "table_max_rate_deg_s = 500.0", "table_max_rate_deg_s = -5.0")),
        ("limit infinite", sub(c, "table_max_rate_deg_s = 500.0", "table_max_rate_deg_s = inf")),
        ("chamber range inverted", sub(c, "chamber_min_temp_c = -60.0", "chamber_min_temp_c = 300.0")),
        ("no sample rates", sub(c, "[1.0, 20.0, 200.0]", "[]")),
        ("sample rate zero", sub(c, "[1.0, 20.0, 200.0]", "[0.0, 20.0]")),
        ("table without endpoint", sub(c, 'endpoint = { tcp = { addr = "127.0.0.1:62000" } }\n', "")),
        ("bad dialect", sub(c, 'dialect = "actidyn"', 'dialect = "acme"')),
        ("bad endpoint kind", sub(c, '{ tcp = { addr = "127.0.0.1:62000" } }', '{ udp = { addr = "127.0.0.1:62000" } }')),
        ("bad address", sub(c, '"127.0.0.1:62000"', '"not an address"')),
        ("baud is a string", sub(c, "baud = 9600", 'baud = "fast"')),
        ("baud zero", sub(c, "baud = 9600", "baud = 0")),
        ("unknown map preset", sub(c, 'map = "watlow_f4t"', 'map = "watlow_f9"')),
        ("custom map incomplete", sub(c, 'map = "watlow_f4t"\n', "") + CUSTOM_MAP),
        ("unit id out of range", sub(c, "unit_id = 1", "unit_id = 300")),
        ("unknown gyro driver", sub(c, 'driver = "can"', 'driver = "laser"')),
        ("gyro without driver", sub(c, 'driver = "can"\n', "")),
        ("CAN id too large", sub(c, "sample_rate_hz = 20.0", "sample_rate_hz = 20.0\nids = { delta_angle = 0x1000, housekeeping = 0x181, info = 0x182 }")),
        ("gyro sample rate negative", sub(c, "sample_rate_hz = 20.0", "sample_rate_hz = -20.0")),
        ("only a table", c.split("[chamber]")[0]),
        ("acceptance negative", c + "\n[acceptance]\nbias_rad_s = -1.0\n"),
        ("simulation effect unknown", "[site]\nlatitude_deg = 45.0\n\n[simulation.effects]\nwarp = { factor = 9 }\n"),
        ("simulation effect zero time constant", "[site]\nlatitude_deg = 45.0\n\n[simulation.effects]\nwarm_up = { amplitude_rad_s = 1e-7, time_constant_s = 0 }\n"),
        ("replay speed zero", '[replay]\nrecording = "x.mcap"\nspeed = 0\n'),
        ("replay with devices", '[replay]\nrecording = "x.mcap"\n\n' + c),
        ("replay of a missing file", '[replay]\nrecording = "no-such-recording.mcap"\n'),
        ("replay recording is a number", "[replay]\nrecording = 5\n"),
        ("invalid UTF-8", CONFIG.encode().replace(b"/dev/ttyUSB0", b"/dev/tty\xff\xfe")),
        ("binary garbage", bytes(random.Random(2).randrange(256) for _ in range(1500))),
    ]
    for cut in (15, 120, 400, len(c.encode()) - 5):
        cases.append((f"truncated at byte {cut}", c.encode()[:cut]))
    return [(n, x if isinstance(x, bytes) else x.encode()) for n, x in cases]


# ------------------------------------------------------------------------------ model files

MODEL = """\
[source]
software = "hand-written"
method = "bad inputs"

[gyro_model]
bias_rad_s = 4.8481368e-8
scale_factor_error = 20e-6
reference_temperature_c = 20.0
temp_coeff_rad_s_per_c = 3.8785e-9
temp_rate_coeff_rad_s_per_c_s = 1.616e-5
arw_rad_per_sqrt_s = 2.908882e-8
bias_instability_rad_s = 9.2496555e-9
earth_rate = true
thermal_time_constant_s = 300.0

[effects]
warm_up = { amplitude_rad_s = 3e-7, time_constant_s = 600.0 }
"""


def models() -> list[tuple[str, bytes]]:
    m = MODEL
    cases: list[tuple[str, str | bytes]] = [
        ("empty file", ""),
        ("syntax error", sub(m, "[gyro_model]", "[gyro_model")),
        ("missing [gyro_model]", m.split("[gyro_model]")[0]),
        ("missing key", sub(m, "bias_rad_s = 4.8481368e-8\n", "")),
        ("unknown key", sub(m, "earth_rate = true", "earth_rate = true\nbias_deg_h = 0.01")),
        ("bias is a string", sub(m, "bias_rad_s = 4.8481368e-8", 'bias_rad_s = "small"')),
        ("bias infinite", sub(m, "bias_rad_s = 4.8481368e-8", "bias_rad_s = inf")),
        ("bias 1e400", sub(m, "bias_rad_s = 4.8481368e-8", "bias_rad_s = 1e400")),
        ("arw negative", sub(m, "arw_rad_per_sqrt_s = 2.908882e-8", "arw_rad_per_sqrt_s = -2.9e-8")),
        ("scale factor below -1", sub(m, "scale_factor_error = 20e-6", "scale_factor_error = -2.0")),
        ("thermal time constant NaN", sub(m, "thermal_time_constant_s = 300.0", "thermal_time_constant_s = nan")),
        ("earth_rate is a string", sub(m, "earth_rate = true", 'earth_rate = "yes"')),
        ("gyro_model is a number", "gyro_model = 5\n"),
        ("duplicate [gyro_model]", m + "\n[gyro_model]\nbias_rad_s = 0.0\n"),
        ("unknown effect", sub(m, "warm_up = {", "warp = {")),
        ("effect time constant zero", sub(m, "time_constant_s = 600.0", "time_constant_s = 0.0")),
        ("effect parameter missing", sub(m, "amplitude_rad_s = 3e-7, ", "")),
        ("effect parameter wrong type", sub(m, "amplitude_rad_s = 3e-7", 'amplitude_rad_s = "big"')),
        ("effect is a number", sub(m, "warm_up = { amplitude_rad_s = 3e-7, time_constant_s = 600.0 }", "warm_up = 3")),
        ("uncertainty wrong type", m + "\n[uncertainty]\nbias_rad_s = \"tiny\"\n"),
        ("source wrong type", sub(m, 'software = "hand-written"', "software = 1")),
        ("invalid UTF-8", MODEL.encode().replace(b"hand-written", b"hand\xff\xfewritten")),
        ("binary garbage", bytes(random.Random(3).randrange(256) for _ in range(1000))),
        ("an MCAP magic and nothing else", b"\x89MCAP0\r\n"),
    ]
    for cut in (10, 100, 250, len(m.encode()) - 4):
        cases.append((f"truncated at byte {cut}", m.encode()[:cut]))
    return [(n, x if isinstance(x, bytes) else x.encode()) for n, x in cases]


# ------------------------------------------------------------------------------ recordings


def rewrite(src: bytes, edit) -> bytes:
    """Copy the MCAP file `src` record by record through the `mcap` package, with `edit`
    (schema, channel, message, metadata) deciding what is written instead."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    out = io.BytesIO()
    reader = make_reader(io.BytesIO(src))
    w = Writer(out)
    w.start(profile="", library="bad_inputs.py")
    schemas: dict[int, int] = {}
    channels: dict[int, int] = {}
    counts: dict[str, int] = {}
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        if schema is not None and schema.id not in schemas:
            name, encoding, data = edit("schema", (schema.name, schema.encoding, schema.data))
            schemas[schema.id] = w.register_schema(name, encoding, data)
        if channel.id not in channels:
            topic, enc = edit("channel", (channel.topic, channel.message_encoding))
            channels[channel.id] = w.register_channel(
                topic, enc, schemas.get(channel.schema_id, 0), dict(channel.metadata)
            )
        k = counts.get(channel.topic, 0)
        counts[channel.topic] = k + 1
        data = edit("message", (channel.topic, k, message.data))
        if isinstance(data, tuple):  # an edit of other records passes messages through
            data = data[2]
        w.add_message(channels[channel.id], message.log_time, data, message.publish_time, message.sequence)
    for md in reader.iter_metadata():
        name, entries = edit("metadata", (md.name, dict(md.metadata)))
        w.add_metadata(name, entries)
    w.finish()
    return out.getvalue()


def json_edit(topic: str, index: int, change):
    """An `edit` that passes everything through but message `index` of `topic`, whose JSON
    body `change` rewrites (a dict in, a dict, list or bytes out)."""

    def edit(kind, value):
        if kind == "message":
            t, k, data = value
            if t == topic and k == index:
                body = change(json.loads(data))
                return body if isinstance(body, bytes) else json.dumps(body).encode()
            return data
        return value

    return edit


def meta_edit(name: str, change):
    def edit(kind, value):
        if kind == "metadata" and value[0] == name:
            return name, change(dict(value[1]))
        return value

    return edit


def setkey(d: dict, key: str, v):
    d = dict(d)
    d[key] = v
    return d


def recordings(src: bytes) -> list[tuple[str, bytes]]:
    n = len(src)
    cases: list[tuple[str, bytes]] = [("empty file", b""), ("magic only", src[:8]), ("text file", b"hello\n" * 100)]
    for at in (1, 7, 9, 17, 100, 1000, 4096, n // 10, n // 3, n // 2, (9 * n) // 10, n - 100, n - 9, n - 1):
        cases.append((f"truncated at byte {at}", src[:at]))
    for seed in range(8):
        rng = random.Random(100 + seed)
        b = bytearray(src)
        flips = 1 if seed < 4 else 20
        for _ in range(flips):
            i = rng.randrange(n)
            b[i] ^= 1 << rng.randrange(8)
        cases.append((f"{flips} bit flip(s), seed {seed}", bytes(b)))
    for at in (0, 8, 200, n // 4, n // 2, n - 4096):
        b = bytearray(src)
        b[at : at + 4096] = bytes(min(4096, n - at))
        cases.append((f"4 KiB zeroed at byte {at}", bytes(b)))
    # Wrong types in message bodies and metadata, wrong encodings: written through `mcap`.
    edits = [
        ("gyro rate is a string", json_edit("/gyro/rate", 100, lambda d: setkey(d, "rate", "fast"))),
        ("gyro seq is negative", json_edit("/gyro/rate", 100, lambda d: setkey(d, "seq", -1))),
        ("gyro status is a float", json_edit("/gyro/rate", 5, lambda d: setkey(d, "status", 0.5))),
        ("gyro body is null", json_edit("/gyro/rate", 50, lambda d: None)),
        ("gyro body is a list", json_edit("/gyro/rate", 50, lambda d: [1, 2, 3])),
        ("gyro body is not JSON", json_edit("/gyro/rate", 50, lambda d: b"\xff{not json")),
        ("gyro body misses every field", json_edit("/gyro/rate", 50, lambda d: {})),
        ("table rate is an object", json_edit("/table/state", 10, lambda d: setkey(d, "rate", {"x": 1}))),
        ("table body is a number", json_edit("/table/state", 0, lambda d: 42)),
        ("chamber temperature is a string", json_edit("/chamber/state", 3, lambda d: setkey(d, "temperature", "hot"))),
        ("chamber body is empty", json_edit("/chamber/state", 3, lambda d: b"")),
        ("step event body wrong", json_edit("/bench/step", 0, lambda d: {"step": "one", "event": 7})),
        ("step index is a string", json_edit("/bench/step", 2, lambda d: setkey(d, "index", "two"))),
        ("table angle is null", json_edit("/table/state", 20, lambda d: setkey(d, "angle", None))),
        ("gyro rate is huge", json_edit("/gyro/rate", 30, lambda d: setkey(d, "rate", 1e308))),
        ("site latitude is text", meta_edit("bench.site", lambda m: setkey(m, "latitude_deg", "north"))),
        ("site latitude out of range", meta_edit("bench.site", lambda m: setkey(m, "latitude_deg", "123"))),
        ("site metadata empty", meta_edit("bench.site", lambda m: {})),
        ("model bias is text", meta_edit("bench.gyro_model", lambda m: setkey(m, "bias", "abc"))),
        ("model arw NaN", meta_edit("bench.gyro_model", lambda m: setkey(m, "arw", "NaN"))),
        ("model effect parameter is text", meta_edit("bench.gyro_model", lambda m: setkey(m, "effect.rate_ripple.relative_amplitude", "x"))),
        ("run metadata empty", meta_edit("bench.run", lambda m: {})),
        (
            "gyro message encoding is cbor",
            lambda k, v: (v[0], "cbor") if k == "channel" and v[0] == "/gyro/rate" else v,
        ),
        (
            "schema encoding is protobuf",
            lambda k, v: (v[0], "protobuf", v[2]) if k == "schema" else v,
        ),
        (
            "gyro topic renamed",
            lambda k, v: ("/gyro/rates", v[1]) if k == "channel" and v[0] == "/gyro/rate" else v,
        ),
    ]
    for name, edit in edits:
        cases.append((name, rewrite(src, edit)))
    return cases


# ------------------------------------------------------------------------------ running

TOML_LOC = r"{file}:\d+:\d+:"
MCAP_MAGIC = b"\x89MCAP0\r\n"
REC_PLACE = re.compile(
    r"byte \d+|message sequence \d+|channel id \d+|/gyro/rate|/table/state|/chamber/state"
    r"|/bench/step|/log\b|bench\.(run|site|scenario|gyro_model|station|acceptance)"
)


@dataclass
class Run:
    kind: str
    case: str
    verb: str
    outcome: str
    code: int | None
    message: str


def classify(kind: str, path: Path, code: int | None, stderr: str, verdicts: set[int]) -> str:
    if code is None:
        return "hang"
    if code == 101 or code < 0 or "panicked" in stderr:
        return "panic"
    if code == 0 or code in verdicts:
        return "accepted"
    if kind == "recording":
        named = str(path) in stderr or path.name in stderr
        return "error" if named and REC_PLACE.search(stderr) else "unlocated"
    if re.search(TOML_LOC.format(file=re.escape(str(path))), stderr):
        return "error"
    # A model file may be a recording (`--model REC.mcap`): one that starts with MCAP's magic
    # is judged as a recording.
    if kind == "model file" and path.read_bytes()[:8] == MCAP_MAGIC:
        return "error" if (path.name in stderr and REC_PLACE.search(stderr)) else "unlocated"
    return "unlocated"


def run(bench: str, kind: str, case: str, verb: str, argv: list[str], path: Path, timeout: float, verdicts=frozenset()) -> Run:
    try:
        p = subprocess.run(
            [bench, *argv], capture_output=True, timeout=timeout, env={**os.environ, "NO_COLOR": "1"}
        )
        code, err = p.returncode, p.stderr.decode(errors="replace")
    except subprocess.TimeoutExpired:
        code, err = None, ""
    msg = next((ln for ln in err.splitlines() if ln.strip()), "")
    return Run(kind, case, verb, classify(kind, path, code, err, set(verdicts)), code, msg)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bench", default=os.environ.get("BENCH_BIN", str(ROOT / "target/debug/bench")))
    ap.add_argument("--recording", default=str(ROOT / "recordings/demo-null.mcap"))
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="recordings: info and recover only (no calibrate/diagnose)")
    ap.add_argument("--keep", help="write the broken inputs to this directory and keep them")
    ap.add_argument("--verbose", "-v", action="store_true")
    args = ap.parse_args()

    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench-bad-inputs-"))
    work.mkdir(parents=True, exist_ok=True)
    jobs = []  # (kind, case, verb, argv, path, verdicts)

    def put(kind: str, i: int, case: str, data: bytes, ext: str) -> Path:
        p = work / f"{kind}-{i:02d}.{ext}"
        p.write_bytes(data)
        return p

    base_s = put("scenario", 99, "base", SCENARIO.encode(), "toml")
    # For `validate --bench replay:REC`: the base scenario at the demo recordings' gyro rate.
    base_r = put("scenario", 98, "base", sub(SCENARIO, '"20 Hz"', '"2 Hz"').encode(), "toml")
    for i, (case, data) in enumerate(scenarios()):
        p = put("scenario", i, case, data, "toml")
        jobs.append(("scenario", case, "validate", ["validate", str(p)], p, ()))
    for i, (case, data) in enumerate(configs()):
        p = put("config", i, case, data, "toml")
        jobs.append(("bench config", case, "validate --bench", ["validate", str(base_s), "--bench", str(p)], p, ()))
    rec = Path(args.recording)
    for i, (case, data) in enumerate(models()):
        p = put("model", i, case, data, "toml")
        # The model is read first; a model that loads is then used for a diagnosis.
        jobs.append(("model file", case, "diagnose --model", ["diagnose", str(rec), "--model", str(p), "--no-report", "-q", "--out", str(work / f"diag-model-{i}")], p, (6, 7)))
    src = rec.read_bytes()
    for i, (case, data) in enumerate(recordings(src)):
        p = put("recording", i, case, data, "mcap")
        jobs.append(("recording", case, "info", ["info", str(p)], p, ()))
        jobs.append(("recording", case, "model", ["model", str(p)], p, ()))
        out = work / f"recovered-{i}.mcap"
        jobs.append(("recording", case, "recover", ["recover", str(p), str(out), "--force", "-q"], p, ()))
        if not args.quick:
            jobs.append(("recording", case, "calibrate", ["calibrate", str(p), "-q", "--no-report", "--out", str(work / f"cal-{i}")], p, (5, 8, 9)))
            jobs.append(("recording", case, "replay", ["validate", str(base_r), "--bench", f"replay:{p}"], p, ()))

    # Sanity: the unbroken inputs are accepted, or the counts mean nothing.
    for verb, argv, path in [
        ("validate", ["validate", str(base_s)], base_s),
        ("model", ["model", str(rec)], rec),
        ("replay", ["validate", str(base_r), "--bench", f"replay:{rec}"], rec),
    ]:
        r = run(args.bench, "sanity", "base", verb, argv, path, args.timeout)
        if r.outcome != "accepted":
            print(f"the unbroken input is not accepted by `bench {' '.join(argv)}`: {r.code} {r.message}", file=sys.stderr)
            return 2

    with ThreadPoolExecutor(max_workers=args.jobs) as ex:
        results = list(ex.map(lambda j: run(args.bench, j[0], j[1], j[2], j[3], j[4], args.timeout, j[5]), jobs))

    outcomes = ["panic", "hang", "unlocated", "error", "accepted"]
    kinds = ["scenario", "bench config", "model file", "recording"]
    inputs = {k: len({r.case for r in results if r.kind == k}) for k in kinds}
    bad = [r for r in results if r.outcome in ("panic", "hang", "unlocated")]
    for r in results:
        if args.verbose or r in bad:
            print(f"{r.outcome:9} {r.kind:12} {r.verb:17} {r.case:40} exit {r.code}: {r.message[:160]}")
    print()
    print(f"{'input':13} {'inputs':>6} {'runs':>5} " + " ".join(f"{o:>9}" for o in outcomes))
    for k in kinds:
        rs = [r for r in results if r.kind == k]
        print(f"{k:13} {inputs[k]:>6} {len(rs):>5} " + " ".join(f"{sum(r.outcome == o for r in rs):>9}" for o in outcomes))
    rs = results
    print(f"{'total':13} {sum(inputs.values()):>6} {len(rs):>5} " + " ".join(f"{sum(r.outcome == o for r in rs):>9}" for o in outcomes))
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
