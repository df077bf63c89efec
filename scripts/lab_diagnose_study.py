#!/usr/bin/env python3
"""The diagnosis on the independent lab writer's 5 h recordings, over many seeds (issue 14's
table in docs/diagnose.md): per preset, how often the concealed physics is found, named exactly,
and its parameters within 3 sigma; false findings and false unexplained windows on nulls.

    python3 scripts/lab_diagnose_study.py [--seeds N] [--jobs J] [--set KEY=VALUE] [PRESET ...]

Needs the pinned Python (scripts/pyenv.sh) and a release build (cargo build --release -p bench).
Every lab file holds a real 9 ms stamping offset of the gyro against the table, so
`time_offset` is part of every truth. Seeds not named exactly are listed on stderr.
"""
import argparse
import concurrent.futures as cf
import json
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PY = os.path.join(ROOT, "target/pyenv/bin/python3")
WRITER = os.path.join(ROOT, "tests/fixtures/lab/labwriter.py")
# BENCH_BIN: another build of bench (default: this checkout's release build).
BENCH = os.environ.get("BENCH_BIN", os.path.join(ROOT, "target/release/bench"))

# preset -> (the writer's effect key, the library effect that should be named, its k)
HARMONIC = {"effect-1rev": ("once_per_rev", "once_per_revolution", 1),
            "effect-2rev": ("twice_per_rev", "angle_harmonic", 2),
            "effect-3rev": ("three_per_rev", "angle_harmonic", 3)}


# preset -> [(the writer's effect key, the library effect that should be named,
#             [(the writer's parameter, bench's)])]; a bias step's time is the writer's fraction
# of the run.
STEP = ("bias_step", "bias_step", [("step", "step_rad_s"), ("time_s", "time_s")])
WARM = ("warm_up", "warm_up", [("amplitude", "amplitude_rad_s"),
                               ("time_constant_s", "time_constant_s")])
LIBRARY = {"effect-step": [STEP],
           "effect-warmup": [WARM],
           "effect-warmup-step": [WARM, STEP],
           "effect-periodic": [("periodic_bias", "periodic_bias",
                                [("amplitude", "amplitude_rad_s"), ("period_s", "period_s")])],
           "effect-quadratic": [("temperature_quadratic", "temperature_quadratic",
                                 [("coeff", "coeff_rad_s_per_c2")])],
           "effect-sf-temperature": [("sf_temperature", "scale_factor_temperature",
                                      [("coeff_per_c", "coeff_per_c")])],
           "effect-hysteresis": [("hysteresis", "thermal_hysteresis",
                                  [("half_width", "half_width_rad_s")])],
           "effect-rate-squared": [("rate_squared", "rate_squared",
                                    [("coeff", "coeff_s_per_rad")])],
           "effect-ripple": [("rate_ripple", "rate_ripple",
                              [("relative_amplitude", "relative_amplitude"),
                               ("phase", "phase_rad")])]}


def within(p, value):
    return abs(p["value"] - value) <= 3.0 * p["sigma"]


def judge(preset, d, truth):
    """(found, named exactly, params within 3σ or None, false finding, false unexplained)."""
    acc = [f["effect"] for f in d["findings"]]
    others = [e for e in acc if e != "time_offset"]
    unexpl = d["unexplained"]
    if preset == "lab-null":
        return (True, not others and not unexpl, None, bool(others), bool(unexpl))
    if preset in HARMONIC:
        key, effect, k = HARMONIC[preset]
        t = truth["effects"][key]["parameters"]
        f = next((f for f in d["findings"] if f["effect"] == effect), None)
        found = f is not None and round(f["parameters"]["cycles_per_rev"]["value"]) == k
        named = found and others == [effect] and not unexpl
        ok = None
        if found:
            ok = within(f["parameters"]["amplitude_rad_s"], t["amplitude"])
            ph = f["parameters"]["phase_rad"]
            dphi = math.remainder(ph["value"] - t["phase"], 2 * math.pi)
            ok = ok and abs(dphi) <= 3 * ph["sigma"]
        return (found, named, ok, any(e != effect for e in others), bool(unexpl))
    if preset in LIBRARY:
        want = [e for _, e, _ in LIBRARY[preset]]
        found, ok = True, True
        for key, effect, params in LIBRARY[preset]:
            t = dict(truth["effects"][key]["parameters"])
            if t.get("time_s", 0) is None:
                t["time_s"] = t["time_fraction"] * truth["duration_s"]
            f = next((f for f in d["findings"] if f["effect"] == effect), None)
            found = found and f is not None
            ok = ok and f is not None and all(within(f["parameters"][b], t[a])
                                              for a, b in params)
        named = found and sorted(others) == sorted(want) and not unexpl
        return (found, named, ok if found else None, any(e not in want for e in others),
                bool(unexpl))
    if preset == "effect-time-offset":
        # The gyro's tags late by 5 ms beyond the lab's stamping: the offset named is the
        # realised one of gyro against table (about -4 ms instead of the null's -9 ms).
        realised = truth["traits"]["realised_stamp_offset_s"]
        want = realised["gyro"]["mean"] - realised["table"]["mean"]
        f = next((f for f in d["findings"] if f["effect"] == "time_offset"), None)
        ok = f is not None and within(f["parameters"]["offset_s"], want)
        return (f is not None, f is not None and not others and not unexpl,
                ok if f is not None else None, bool(others), bool(unexpl))
    if preset == "effect-sawtooth":
        found = any("P/2" in u["correlates_with"] or "periodic_bias-like" in u["correlates_with"]
                    for u in unexpl)
        return (found, found and not others and len(unexpl) == 1, None, bool(others), False)
    if preset == "effect-gradient":
        eff = truth["effects"]["temperature_gradient"]["effective_temp_rate_coeff"]
        u = d["parameter_updates"]["temp_rate_coeff"]
        ok = abs(u["fitted"] - eff) <= 3 * u["sigma"]
        # The lag against temp_rate_coeff, alone or in a set of terms ("a + b").
        caveat = any(c["effect"] == "thermal_lag" and "temp_rate_coeff" in c["with"].split(" + ")
                     for c in d["identifiability"])
        return (caveat, caveat and not others and not unexpl, ok, bool(others), bool(unexpl))
    raise SystemExit(f"no judgement for {preset}")


def one(preset, seed, tmp, sets=()):
    mcap = os.path.join(tmp, f"{preset}-{seed}.mcap")
    extra = [x for kv in sets for x in ("--set", kv)]
    subprocess.run([PY, WRITER, mcap, "--preset", preset, "--seed", str(seed), *extra],
                   check=True, stdout=subprocess.DEVNULL)
    out = os.path.join(tmp, f"{preset}-{seed}.json")
    import time
    t0 = time.time()
    subprocess.run([BENCH, "diagnose", mcap, "-q", "--no-report", "--json", out,
                    "-o", os.path.join(tmp, f"d-{preset}-{seed}")], stdout=subprocess.DEVNULL)
    secs = time.time() - t0
    truth = json.load(open(mcap[:-5] + ".truth.json"))
    d = json.load(open(out))
    for f in (mcap, mcap[:-5] + ".truth.json"):
        os.remove(f)
    verdict = judge(preset, d, truth)
    if not verdict[1]:
        # Which seed missed, and how: for the note and for a rerun with the writer.
        found = [f["effect"] for f in d["findings"]]
        unexpl = [u["correlates_with"] for u in d["unexplained"]]
        print(f"{preset} seed {seed}: not named exactly: found {found}, unexplained {unexpl}",
              file=sys.stderr, flush=True)
    return verdict + (secs,)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                    help="the writer's override, passed to every file (e.g. "
                         "traits.table_device_time=false)")
    ap.add_argument("presets", nargs="*", default=["lab-null", "effect-2rev", "effect-3rev",
                                                      "effect-sawtooth", "effect-gradient"])
    a = ap.parse_args()
    print("| preset | seeds | found | named exactly | parameters within 3σ | false findings "
          "| false unexplained | median diagnose s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp, cf.ThreadPoolExecutor(a.jobs) as ex:
        for preset in a.presets:
            rows = list(ex.map(lambda s: one(preset, s, tmp, a.set), range(1, a.seeds + 1)))
            n = len(rows)
            pct = lambda i: f"{100 * sum(1 for r in rows if r[i]) / n:.0f} %"
            oks = [r[2] for r in rows if r[2] is not None]
            within3 = f"{100 * sum(oks) / len(oks):.0f} %" if oks else "—"
            secs = sorted(r[5] for r in rows)[n // 2]
            print(f"| {preset} | {n} | {pct(0)} | {pct(1)} | {within3} | {pct(3)} | {pct(4)} "
                  f"| {secs:.1f} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
