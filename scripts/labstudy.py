"""What the lab-writer studies share (`scripts/calibrate_study.py`,
`scripts/lab_diagnose_study.py`): the pinned interpreter, the independent writer, bench's
release build, and one drawn configuration written and turned into a recording."""
import json
import os
import random
import subprocess
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PY = os.path.join(ROOT, "target/pyenv/bin/python3")
WRITER = os.path.join(ROOT, "tests/fixtures/lab/labwriter.py")
BENCH = os.environ.get("BENCH_BIN", os.path.join(ROOT, "target/release/bench"))


def write_lab(d, cfg, preset, seed):
    """`cfg` (a labwriter config, merged over `preset`) written to `d/config.json` and the
    writer run on it with `seed` into `d/run.mcap` (its truth beside it; not rewritten when a
    finished one is there): (path of the recording, seconds it took, None) or (None, seconds,
    what went wrong)."""
    os.makedirs(d, exist_ok=True)
    conf = os.path.join(d, "config.json")
    with open(conf, "w") as f:
        json.dump(cfg, f, indent=1)
    mcap = os.path.join(d, "run.mcap")
    done = mcap[:-5] + ".done"
    t0 = time.time()
    if not (os.path.exists(mcap) and os.path.exists(done)):
        w = subprocess.run([PY, WRITER, mcap, "--preset", preset, "--seed", str(seed),
                            "--config", conf, "-q"], capture_output=True, text=True)
        if w.returncode != 0:
            return None, time.time() - t0, "writer: " + w.stderr.strip()[-400:]
        open(done, "w").close()
    return mcap, time.time() - t0, None


def shorten(legs, hours):
    """The first legs of a drawn chamber profile that fill `hours` (a ramp cut at the budget
    stops at the temperature it reached): a shorter procedure of the same kind, within the
    issue's ranges (holds 10–60 min, ramps 0.5–3 °C/min, at least one ramp)."""
    out, total, temp = [], 0.0, 20.0
    budget = hours * 3600.0
    for leg in legs:
        if total >= budget and any("to_c" in x for x in out):
            break
        if "hold_s" in leg:
            out.append(dict(leg))
            total += leg["hold_s"]
            continue
        span = abs(leg["to_c"] - temp) / leg["rate_c_min"] * 60.0
        left = budget - total
        if span > left and any("to_c" in x for x in out) and left > 600.0:
            frac = left / span
            to = round(temp + frac * (leg["to_c"] - temp))
            out.append({"to_c": float(to), "rate_c_min": leg["rate_c_min"]})
            total = budget
            temp = to
            continue
        out.append(dict(leg))
        total += span
        temp = leg["to_c"]
    return out


def hours_of(seed, hours):
    """The procedure's length for `seed` when the study asks for `hours` (lo, hi): drawn from
    a stream of its own, so every other draw of the seed is unchanged."""
    return random.Random(seed * 7 + 3).uniform(*hours)
