#!/usr/bin/env python3
"""`bench calibrate` over lab-writer recordings of procedures drawn at random (issue 27's
studies, docs/calibrate.md): thresholds judged on each recording's own design and noise, not on
the shapes we tried.

    python3 scripts/calibrate_study.py nulls    [--files N] [--first-seed S] [--hours LO-HI]
    python3 scripts/calibrate_study.py coverage [--files N] [--first-seed S] [--hours LO-HI]
    python3 scripts/calibrate_study.py seed     [--files N] [--first-seed S] [--jobs J]

`nulls`: complete models (nothing concealed), procedures drawn at random — ramps or soaks,
1–3 table rates of 2–30 °/min, reversals every 4–15 min, the gyro at 10–50 Hz, every lab trait
of `lab-null` and a chamber whose air cycles (0.01–0.05 °C at 2–10 min, read at 1–20 Hz in
0.1 °C steps), with or without the gyro's own sensor (lag 200–1200 s). Prints how many fits are
called poor, by which check, and every coefficient's z against the truth.

Every drawn gyro's flicker has run 30 000 s before the record (`--flicker-history-s`, a gyro
powered for hours; 0 for the writer's cold start, the studies before session 39).

`coverage`: gyros without a temperature sensor whose coil lags the air by 200–1200 s, on the
same random procedures; per coefficient and domain the coverage of the stated 95 % interval
(|z| ≤ 1.96) and the RMS of z.

`seed`: bench's own recordings of `scenarios/seed.toml` (`bench run --seed N`), calibrated;
the same table against the recording's `bench.gyro_model`. The seed has only 360 s of
constant-temperature windows, so its noise model comes from every window's residual.

Needs the pinned Python (scripts/pyenv.sh) and a release build (cargo build --release -p bench);
BENCH_BIN names another build. The writer's config-write and call are `scripts/labstudy.py`'s,
shared with `scripts/lab_diagnose_study.py`. `--hours 2-3` cuts each drawn procedure to its
first legs (a length drawn from a stream of its own: every other draw is unchanged); the cost of
a file is mostly the writer's (≈ 10 s per hour of a 50 Hz gyro) and `bench calibrate`'s
(≈ 10–20 s), so a 100-file study of 2–3 h procedures takes ≈ 40 min on one core. `--keep`
with `--log OTHER.jsonl` and another BENCH_BIN calibrates the kept recordings again (the
writer is not rerun where a finished recording is there). Each file: the writer's config and truth in WORK/seed-N/, the
result JSON beside it; `--keep` keeps the recordings. A table per run goes to stdout, the
per-file lines to WORK/results.jsonl.
"""
import argparse
import concurrent.futures as cf
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time

from labstudy import BENCH, ROOT, hours_of, shorten, write_lab
KEYS = ["bias", "scale_factor_error", "temp_coeff", "temp_rate_coeff"]
# The flicker's past in the drawn labs (`gyro.flicker_history_s`): a real gyro has been on for
# hours before a calibration run. The writer's default (0) starts its Kasdin–Walter flicker at
# the first sample, whose record mean then wanders less than a running gyro's (σ 0.70× over
# 3 h), and bench's σ(bias) — the stationary flicker's, slowest component 30 000 s — read as
# too large (RMS z 0.47–0.54 on the coverage study's seeds 1–11; with this history
# 0.84–0.94). Only the studies use it: the fixtures keep the writer's default.
FLICKER_HISTORY_S = 30000.0


def draw_legs(g):
    """The chamber's legs: "ramps" (continuous ramps, holds of at most 10 min) or "soaks"
    (plateaus of 30–60 min joined by fast moves), 2–5 h, within −40..+60 °C."""
    kind = g.choice(["ramps", "soaks"])
    legs = [{"hold_s": g.uniform(300, 900)}]
    temp, total = 20.0, legs[0]["hold_s"]
    budget = g.uniform(2.0, 5.0) * 3600.0
    while total < budget:
        target = temp
        while abs(target - temp) < 15.0:
            target = round(g.uniform(-40.0, 60.0))
        rate = g.uniform(0.5, 3.0) if kind == "ramps" else g.uniform(2.0, 4.0)
        hold = g.uniform(0.0, 600.0) if kind == "ramps" else g.uniform(1800.0, 3600.0)
        legs.append({"to_c": float(target), "rate_c_min": round(rate, 3)})
        if hold >= 60.0:
            legs.append({"hold_s": round(hold)})
        total += abs(target - temp) / rate * 60.0 + hold
        temp = target
    return kind, legs


def draw(seed, no_sensor=None):
    """A random procedure and lab as a labwriter config (merged over `lab-null`)."""
    g = random.Random(seed * 7919 + 17)
    kind, legs = draw_legs(g)
    rates = [round(g.uniform(2.0, 30.0), 2) for _ in range(g.randint(1, 3))]
    sensor = (g.random() < 0.5) if no_sensor is None else not no_sensor
    cfg = {
        "procedure": {"legs": legs, "rates_deg_min": rates, "rate_deg_min": rates[0],
                      "segment_s": round(g.uniform(240.0, 900.0)),
                      "first_direction": g.choice(["cw", "ccw"])},
        "gyro": {"sample_rate_hz": g.choice([10.0, 20.0, 25.0, 40.0, 50.0]),
                 "sensor": sensor,
                 "thermal_time_constant": round(g.uniform(200.0, 1200.0))},
        "traits": {"chamber_rate_hz": g.choice([1.0, 2.0, 10.0, 20.0]),
                   "chamber_cycling": {"enabled": True,
                                       "amplitude_c": round(g.uniform(0.01, 0.05), 4),
                                       "period_s": round(g.uniform(120.0, 600.0)),
                                       "shape": g.choice(["sine", "triangle"]),
                                       "duty": round(g.uniform(0.3, 0.7), 3),
                                       "phase_s": round(g.uniform(0.0, 600.0), 1)}},
    }
    return kind, cfg


def zs_of(res, t, held, row):
    """Each estimated coefficient's z against the truth `t`, both domains, into `row`."""
    for k in KEYS:
        c = res["coefficients"].get(k)
        if c and k not in held and c.get("sigma"):
            row["z"][k] = (c["value"] - t[k]) / c["sigma"]
        a = ((res.get("angle_domain") or {}).get("coefficients") or {}).get(k)
        if a and k not in held and a.get("sigma"):
            row["z_angle"][k] = (a["value"] - t[k]) / a["sigma"]
    return row


def calibrated(args, d, mcap, bench=BENCH, name="result.json", remove=True):
    """`bench calibrate` of `mcap` into `d` (the recording removed unless --keep or not
    `remove`): (result JSON, exit code), or (None, what went wrong)."""
    out = os.path.join(d, name)
    t0 = time.time()
    cal = os.path.join(d, "cal" + name[len("result"):-len(".json")])
    r = subprocess.run([bench, "calibrate", mcap, "-o", cal, "--json", out, "--no-report",
                        "--keep-poor-fit", "--force", "-q"], capture_output=True, text=True)
    if not os.path.exists(out):
        return None, f"bench exit {r.returncode}: {r.stderr.strip()[-400:]}"
    res = json.load(open(out))
    res["calibrate_secs"] = time.time() - t0
    if remove and not args.keep:
        os.remove(mcap)
    return res, r.returncode


def verdict_of(res, code, t):
    """What one calibration said and its z against the truth `t`."""
    held = set((res.get("held") or {}).keys())
    row = {"exit": code, "verdict": res["fit"]["verdict"],
           "failed": [c["key"] for c in res["fit"]["checks"] if not c["passed"]],
           "checks": {c["key"]: c["value"] for c in res["fit"]["checks"]},
           "lag_fit": res.get("thermal_time_constant"),
           "lag_sigma": res.get("thermal_time_constant_sigma"),
           "held": sorted(held), "z": {}, "z_angle": {},
           "calibrate_secs": res["calibrate_secs"]}
    return zs_of(res, t, held, row)


def one_seed(args, seed):
    """`scenarios/seed.toml` run by bench's simulated bench with `--seed seed`, calibrated."""
    d = os.path.join(args.work, f"seed-{seed}")
    os.makedirs(d, exist_ok=True)
    mcap = os.path.join(d, "run.mcap")
    w = subprocess.run([BENCH, "run", os.path.join(ROOT, "scenarios/seed.toml"), "--seed",
                        str(seed), "--out", mcap, "--force", "-q"], capture_output=True, text=True)
    if w.returncode != 0:
        return {"seed": seed, "error": "run: " + w.stderr.strip()[-400:]}
    res, code = calibrated(args, d, mcap)
    if res is None:
        return {"seed": seed, "error": code}
    held = set((res.get("held") or {}).keys())
    row = {"seed": seed, "kind": "seed", "exit": code, "verdict": res["fit"]["verdict"],
           "failed": [c["key"] for c in res["fit"]["checks"] if not c["passed"]],
           "checks": {c["key"]: c["value"] for c in res["fit"]["checks"]},
           "sensor": True, "lag_true": None, "lag_fit": None, "lag_sigma": None,
           "rates": [10.0], "segment_s": 720, "hz": 20.0, "held": sorted(held),
           "z": {}, "z_angle": {}}
    return zs_of(res, res["truth"]["coefficients"], held, row)


def one(args, seed):
    if args.study == "seed":
        return one_seed(args, seed)
    kind, cfg = draw(seed, no_sensor=args.study == "coverage" or None)
    if args.flicker_history_s:
        cfg["gyro"]["flicker_history_s"] = args.flicker_history_s
    if args.hours:
        cfg["procedure"]["legs"] = shorten(cfg["procedure"]["legs"], hours_of(seed, args.hours))
    mcap, write_secs, err = write_lab(os.path.join(args.work, f"seed-{seed}"), cfg,
                                      "lab-null", seed)
    if err:
        return {"seed": seed, "error": err}
    d = os.path.dirname(mcap)
    truth = json.load(open(mcap[:-5] + ".truth.json"))
    t = truth["gyro_model"]
    other = None
    if args.compare:
        # The same recording through another build first (`--compare`): its lines beside.
        res, code = calibrated(args, d, mcap, bench=args.compare, name="result-compare.json",
                               remove=False)
        other = verdict_of(res, code, t) if res is not None else {"error": code}
    res, code = calibrated(args, d, mcap)
    if res is None:
        return {"seed": seed, "error": code}
    row = {"seed": seed, "kind": kind, "sensor": cfg["gyro"]["sensor"],
           "lag_true": cfg["gyro"]["thermal_time_constant"],
           "rates": cfg["procedure"]["rates_deg_min"], "segment_s": cfg["procedure"]["segment_s"],
           "hz": cfg["gyro"]["sample_rate_hz"], "hours": truth["duration_s"] / 3600.0,
           "write_secs": write_secs, **verdict_of(res, code, t)}
    if other is not None:
        row["compare"] = other
    return row


def table(rows, study):
    if any("compare" in r for r in rows):
        print("## --compare build (the same recordings)")
        table([{**{k: v for k, v in r.items() if k != "compare"}, **r["compare"]} for r in rows
               if "compare" in r and "error" not in r and "error" not in r["compare"]], study)
        print("\n## this build")
    ok = [r for r in rows if "error" not in r]
    print(f"{len(ok)} files ({len(rows) - len(ok)} failed to run)")
    for r in rows:
        if "error" in r:
            print(f"  seed {r['seed']}: {r['error']}", file=sys.stderr)
    poor = [r for r in ok if r["verdict"] == "poor"]
    print(f"verdicts: " + ", ".join(f"{v} {sum(r['verdict'] == v for r in ok)}"
                                    for v in sorted({r['verdict'] for r in ok})))
    print(f"poor: {len(poor)} of {len(ok)} ({100.0 * len(poor) / max(1, len(ok)):.1f} %)")
    by = {}
    for r in poor:
        for k in r["failed"]:
            by[k] = by.get(k, 0) + 1
    for k, n in sorted(by.items()):
        print(f"  {k}: {n}")
    for r in poor:
        print(f"  seed {r['seed']} ({r['kind']}, rates {r['rates']}, {r['hz']:g} Hz, "
              f"sensor {r['sensor']}): {', '.join(r['failed'])} "
              f"{ {k: round(v, 2) for k, v in r['checks'].items()} }")
    held = {}
    for r in ok:
        for k in r["held"]:
            held[k] = held.get(k, 0) + 1
    if held:
        print("held: " + ", ".join(f"{k} {n}" for k, n in sorted(held.items())))
    print()
    print("| coefficient | domain | n | coverage (|z| ≤ 1.96) | RMS z | worst |z| |")
    print("| --- | --- | --- | --- | --- | --- |")
    for dom, field in (("rate", "z"), ("angle", "z_angle")):
        for k in KEYS:
            zs = [r[field][k] for r in ok if k in r[field] and math.isfinite(r[field][k])]
            if not zs:
                continue
            cov = sum(abs(z) <= 1.959964 for z in zs) / len(zs)
            rms = math.sqrt(sum(z * z for z in zs) / len(zs))
            print(f"| {k} | {dom} | {len(zs)} | {100 * cov:.1f} % | {rms:.2f} | "
                  f"{max(abs(z) for z in zs):.1f} |")
    if study == "coverage":
        lags = [(r["lag_true"], r["lag_fit"], r.get("lag_sigma")) for r in ok
                if r["lag_fit"] is not None]
        if lags:
            rel = [abs(f / t - 1.0) for t, f, _ in lags if t > 0]
            rel.sort()
            print(f"\nlag fitted/true − 1: median {100 * rel[len(rel) // 2]:.1f} %, "
                  f"worst {100 * rel[-1]:.1f} %")
            zl = [(f - t) / s for t, f, s in lags if s]
            if zl:
                print(f"lag z: coverage {100 * sum(abs(z) <= 1.96 for z in zl) / len(zl):.1f} %, "
                      f"RMS {math.sqrt(sum(z * z for z in zl) / len(zl)):.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("study", choices=["nulls", "coverage", "seed"])
    ap.add_argument("--files", type=int, default=100)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--work", default=None, help="folder for the files (default: a temp dir)")
    ap.add_argument("--keep", action="store_true", help="keep the recordings")
    ap.add_argument("--flicker-history-s", type=float, default=FLICKER_HISTORY_S,
                    help="the gyro's flicker has run this long before the record (labwriter "
                         "gyro.flicker_history_s; default %(default)g s: a gyro powered for "
                         "hours; 0: the writer's own default, a flicker starting at the first "
                         "sample, as the studies before session 39 ran)")
    ap.add_argument("--hours", default=None,
                    help="LO-HI: cut each drawn procedure to a length drawn in LO..HI h (its "
                         "first legs; the other draws unchanged), e.g. 2-3 (default: as drawn, "
                         "2-5 h)")
    ap.add_argument("--compare", default=None,
                    help="another bench build: each recording is calibrated by it too, and its "
                         "table printed first (a change measured on the same files)")
    ap.add_argument("--log", default="results.jsonl",
                    help="per-file lines, in WORK (another name to calibrate kept recordings "
                         "again with another BENCH_BIN)")
    args = ap.parse_args()
    if args.hours:
        args.hours = tuple(float(x) for x in args.hours.split("-"))
    args.work = args.work or tempfile.mkdtemp(prefix=f"calib-{args.study}-")
    os.makedirs(args.work, exist_ok=True)
    seeds = range(args.first_seed, args.first_seed + args.files)
    rows = []
    with cf.ThreadPoolExecutor(args.jobs) as ex, \
            open(os.path.join(args.work, args.log), "a") as log:
        for row in ex.map(lambda s: one(args, s), seeds):
            rows.append(row)
            log.write(json.dumps(row) + "\n")
            log.flush()
            print(f"seed {row['seed']}: {row.get('verdict', row.get('error'))} "
                  f"{row.get('failed', '')} held {row.get('held', '')}", file=sys.stderr)
    print(f"work: {args.work}", file=sys.stderr)
    table(rows, args.study)


if __name__ == "__main__":
    main()
