"""The three independent peers together, as a bench on virtual ports: the Actidyn table on a
pty (table.py), the Eurotherm 3216 chamber over Modbus RTU on a pty (chamber.py) and the gyro
behind an SLCAN adapter on a pty (gyro.py), at one time scale; writes the bench config that
reaches them and prints one ready line {"ready": "bench", "config": PATH, "logs": DIR}.

    python tests/peers/serve_bench.py --time-scale 15 --out peer.toml &
    bench run tests/peers/scenario.toml --bench peer.toml --out peers.mcap

The peers' command logs are DIR/{table,chamber,gyro}.jsonl. Ends (and ends the peers) when its
stdin closes or on SIGTERM.

--coupled makes one bench of them: the table and chamber peers publish their state
(DIR/{table,chamber}.state.json) and the gyro senses the table's rate and the chamber's air
through them with the thermal error model --gyro-model (gyro.py's text), so that a calibration
of a recording made on the peers means something. --drive-trip-after-rat and --watchdog-s are
passed to the table peer, --bit-fail-after to the gyro peer.
"""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
import sys
import tempfile

import peerlib

HERE = os.path.dirname(os.path.abspath(__file__))

CONFIG = """# Written by tests/peers/serve_bench.py: bench's real drivers against independent peers.
[site]
latitude_deg = {latitude}

[bench]
time_scale = {scale}

[table]
dialect = "actidyn"
endpoint = {{ serial = {{ path = "{table}", baud = 115200 }} }}

[chamber]
endpoint = {{ serial = {{ path = "{chamber}", baud = 9600 }} }}
unit_id = 1
map = "eurotherm_3216"

[gyro]
driver = "can"
transport = {{ kind = "slcan", serial = {{ path = "{gyro}", baud = 115200 }}, bitrate = 500000 }}
sample_rate_hz = 20.0
# 10 periods (0.5 s of bench time) would be 33 ms of wall time at 15x: a Python peer on a
# loaded machine can be that late.
watchdog_periods = 100
"""


def start(script: str, args: list[str], log: str) -> tuple[subprocess.Popen, dict]:
    p = subprocess.Popen(
        [sys.executable, os.path.join(HERE, script), *args, "--log", log],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE,
    )
    line = p.stdout.readline()
    if not line:
        raise SystemExit(f"{script} did not start")
    return p, json.loads(line)


async def main() -> None:
    p = peerlib.base_args(__doc__.splitlines()[0])
    p.add_argument("--out", default="peer.toml", help="bench config to write")
    p.add_argument("--log-dir", help="where the peers' logs go (default: a new temporary dir)")
    p.add_argument("--coupled", action="store_true",
                   help="the gyro senses the table's rate and the chamber's air")
    p.add_argument("--gyro-model", default="{}",
                   help="coupled: gyro model, JSON with bench.gyro_model keys (SI)")
    p.add_argument("--latitude-deg", type=float, default=45.0, help="site latitude")
    p.add_argument("--initial-temp-c", type=float, default=23.0,
                   help="air (and coupled gyro) temperature at start")
    p.add_argument("--chamber-tau-s", type=float, default=20.0,
                   help="the chamber air's lag behind its working set point, bench s")
    p.add_argument("--seed", type=int, default=1, help="coupled: the gyro's noise seed")
    p.add_argument("--watchdog-s", type=float, help="table peer's keep-alive limit, bench s")
    p.add_argument("--drive-trip-after-rat", type=float, metavar="S",
                   help="table peer: drop the drive S bench s after the first rate command")
    p.add_argument("--bit-fail-after", type=float, metavar="S",
                   help="gyro peer: built-in-test bit from S bench s on")
    args = p.parse_args()
    logs = args.log_dir or tempfile.mkdtemp(prefix="bench-peers-")
    os.makedirs(logs, exist_ok=True)
    scale = str(args.time_scale)
    table_args = ["--dialect", "actidyn", "--transport", "pty", "--time-scale", scale]
    chamber_args = ["--model", "eurotherm_3216", "--transport", "rtu", "--time-scale", scale,
                    "--air-c", str(args.initial_temp_c), "--tau-s", str(args.chamber_tau_s)]
    gyro_args = ["--time-scale", scale]
    if args.watchdog_s is not None:
        table_args += ["--watchdog-s", str(args.watchdog_s)]
    if args.drive_trip_after_rat is not None:
        table_args += ["--drive-trip-after-rat", str(args.drive_trip_after_rat)]
    if args.bit_fail_after is not None:
        gyro_args += ["--bit-fail-after", str(args.bit_fail_after)]
    if args.coupled:
        table_state = os.path.join(logs, "table.state.json")
        chamber_state = os.path.join(logs, "chamber.state.json")
        table_args += ["--state", table_state]
        chamber_args += ["--state", chamber_state]
        gyro_args += ["--table-state", table_state, "--chamber-state", chamber_state,
                      "--model", args.gyro_model, "--latitude-deg", str(args.latitude_deg),
                      "--initial-temp-c", str(args.initial_temp_c), "--seed", str(args.seed)]
    table, t = start("table.py", table_args, os.path.join(logs, "table.jsonl"))
    chamber, c = start("chamber.py", chamber_args, os.path.join(logs, "chamber.jsonl"))
    gyro, g = start("gyro.py", gyro_args, os.path.join(logs, "gyro.jsonl"))
    with open(args.out, "w", encoding="utf-8") as f:
        f.write(CONFIG.format(scale=args.time_scale, table=t["pty"], chamber=c["pty"],
                              gyro=g["pty"], latitude=args.latitude_deg))
    peerlib.ready("bench", config=os.path.abspath(args.out), logs=logs)
    await peerlib.run_until_stdin_closes()
    for child in (table, chamber, gyro):
        child.stdin.close()
    for child in (table, chamber, gyro):
        try:
            child.wait(timeout=10)
        except subprocess.TimeoutExpired:
            child.kill()


if __name__ == "__main__":
    asyncio.run(main())
