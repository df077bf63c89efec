"""The three independent peers together, as a bench on virtual ports: the Actidyn table on a
pty (table.py), the Eurotherm 3216 chamber over Modbus RTU on a pty (chamber.py) and the gyro
behind an SLCAN adapter on a pty (gyro.py), at one time scale; writes the bench config that
reaches them and prints one ready line {"ready": "bench", "config": PATH, "logs": DIR}.

    python tests/peers/serve_bench.py --time-scale 15 --out peer.toml &
    bench run tests/peers/scenario.toml --bench peer.toml --out peers.mcap

The peers' command logs are DIR/{table,chamber,gyro}.jsonl. Ends (and ends the peers) when its
stdin closes or on SIGTERM.
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
latitude_deg = 45.0

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
    args = p.parse_args()
    logs = args.log_dir or tempfile.mkdtemp(prefix="bench-peers-")
    os.makedirs(logs, exist_ok=True)
    scale = str(args.time_scale)
    table, t = start("table.py", ["--dialect", "actidyn", "--transport", "pty",
                                  "--time-scale", scale], os.path.join(logs, "table.jsonl"))
    chamber, c = start("chamber.py", ["--model", "eurotherm_3216", "--transport", "rtu",
                                      "--time-scale", scale], os.path.join(logs, "chamber.jsonl"))
    gyro, g = start("gyro.py", ["--time-scale", scale], os.path.join(logs, "gyro.jsonl"))
    with open(args.out, "w", encoding="utf-8") as f:
        f.write(CONFIG.format(scale=args.time_scale, table=t["pty"], chamber=c["pty"],
                              gyro=g["pty"]))
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
