#!/usr/bin/env python3
"""The Python reference of `bench export`'s speed: every message of a recording read with the
`mcap` package and its JSON body decoded with `json.loads` (no table written, so a lower bound
of what a Python export costs).

    scripts/export_reference.py REC.mcap     # prints the message count and the time
"""

import json
import sys
import time

from mcap.reader import make_reader


def main():
    t = time.perf_counter()
    n = 0
    with open(sys.argv[1], "rb") as f:
        for _schema, _channel, message in make_reader(f).iter_messages():
            json.loads(message.data)
            n += 1
    s = time.perf_counter() - t
    print(f"python mcap iter_messages + json.loads: {n} msgs in {s:.3f} s ({n / s:.0f} msgs/s)")


if __name__ == "__main__":
    main()
