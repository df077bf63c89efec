"""python-can's `slcan` interface as an independent CLIENT of the SLCAN adapter peer (gyro.py).

Starts gyro.py, opens python-can's slcan bus on the adapter's pty, receives frames, decodes them
as docs/protocols/gyro-can.md says and compares them with the samples the peer logged; asks the
version and serial number; closes. Prints one JSON line with the result; exits 0 when it holds.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

import can

HERE = os.path.dirname(os.path.abspath(__file__))


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        log_path = os.path.join(tmp, "gyro.jsonl")
        peer = subprocess.Popen(
            [sys.executable, os.path.join(HERE, "gyro.py"), "--log", log_path,
             "--rate-hz", "100", "--seq0", "0xFFFFFFF0", "--status-demo"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        )
        try:
            ready = json.loads(peer.stdout.readline())
            bus = can.Bus(interface="slcan", channel=ready["pty"], bitrate=500_000,
                          sleep_after_open=0)
            frames = []
            while len(frames) < 40:
                msg = bus.recv(timeout=5.0)
                if msg is None:
                    break
                frames.append(msg)
            version = bus.get_version(timeout=2.0)
            serial_number = bus.get_serial_number(timeout=2.0)
            bus.shutdown()
        finally:
            peer.stdin.close()
            peer.wait(timeout=10)
        log = [json.loads(line) for line in open(log_path)]
    sent = {e["sample"]["seq"]: e["sample"] for e in log if "sample" in e}
    commands = [e["rx"] for e in log if "rx" in e]
    problems = []
    decoded = 0
    deltas = {}
    for m in frames:
        d = bytes(m.data)
        if m.is_extended_id or m.dlc != 8:
            problems.append(f"unexpected frame {m}")
        elif m.arbitration_id == 0x180:
            deltas[d[0]] = int.from_bytes(d[1:8], "little", signed=True)
        elif m.arbitration_id == 0x181:
            seq = int.from_bytes(d[0:4], "little")
            status = int.from_bytes(d[4:6], "little")
            temp = int.from_bytes(d[6:8], "little", signed=True)
            s = sent.get(seq)
            if s is None or deltas.get(seq & 0xFF) != s["delta"] or status != s["status"] \
                    or temp != s["temp_centi"]:
                problems.append(f"sample {seq}: frames {deltas.get(seq & 0xFF)} {status} {temp}"
                                f" vs sent {s}")
            else:
                decoded += 1
        elif m.arbitration_id == 0x182:
            if int.from_bytes(d[0:4], "little") != 10_000_000 or d[4] != 40:
                problems.append(f"info frame {d.hex()}")
    if decoded < 10:
        problems.append(f"only {decoded} samples decoded from {len(frames)} frames")
    result = {
        "decoded_samples": decoded,
        "frames": len(frames),
        "version": version,
        "serial_number": serial_number,
        "commands": commands,
        "problems": problems,
    }
    print(json.dumps(result))
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
