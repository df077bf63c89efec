#!/usr/bin/env python3
"""A wired run at real time: a scenario through bench's real drivers against the independent
Python peers (tests/peers/serve_bench.py --coupled: Actidyn table on a pty, Eurotherm 3216 over
Modbus RTU on a pty, a gyro behind an SLCAN adapter on a pty that senses the table's rate and the
chamber's air), and the same scenario and seed in process (virtual time). Reports, for both
recordings, the jitter of each channel's host stamps (p50/p99 of the intervals), replies lost
(answered by a peer, never recorded) and late (an interval over 1.5 periods), the table's reply
latency spread, and the two calibrations side by side.

    P=$(bash scripts/pyenv.sh)
    cargo build --release -p bench
    $P scripts/wired_run.py --out wired-run/          # the seed scenario: 78 min of wall time
    $P scripts/wired_run.py --time-scale 15 --out w15  # a quick look (not real time)

The gyro peer follows the in-process run's true model (its `bench.gyro_model`), at the scenario's
latitude, starting at the in-process run's first air temperature; the chamber peer's air lags
its set point by 120 s, as bench's simulated chamber. Not in CI (docs/protocols/peers.md quotes a
run). Writes OUT/{inproc,wired}.mcap, the calibrations, the peers' logs and OUT/summary.md.
"""

from __future__ import annotations

import argparse
import bisect
import json
import math
import os
import shutil
import subprocess
import sys
import time

from mcap.reader import make_reader

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHANNELS = ("/gyro/rate", "/table/state", "/chamber/state")
COEFFS = ("bias", "scale_factor_error", "temp_coeff", "temp_rate_coeff")


def run(cmd: list[str], log: str | None = None, ok=(0,)) -> int:
    print("$", " ".join(cmd), flush=True)
    out = open(log, "w", encoding="utf-8") if log else None
    r = subprocess.run(cmd, stdout=out or None, stderr=subprocess.STDOUT if out else None)
    if out:
        out.close()
    if r.returncode not in ok:
        tail = open(log, encoding="utf-8").read()[-3000:] if log else ""
        raise SystemExit(f"{cmd[1]} exited {r.returncode}\n{tail}")
    return r.returncode


def read(path: str) -> dict:
    """Per channel: host stamps (s) and bodies; the metadata."""
    out = {c: ([], []) for c in CHANNELS}
    meta = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, channel, message in reader.iter_messages(log_time_order=True):
            if channel.topic in out:
                out[channel.topic][0].append(message.log_time * 1e-9)
                out[channel.topic][1].append(json.loads(message.data))
        f.seek(0)
        for m in make_reader(f).iter_metadata():
            meta[m.name] = dict(m.metadata)
    return {"channels": out, "meta": meta}


def quantile(xs: list[float], q: float) -> float:
    if not xs:
        return float("nan")
    s = sorted(xs)
    i = min(len(s) - 1, max(0, round(q * (len(s) - 1))))
    return s[i]


def jitter(stamps: list[float], period: float) -> dict:
    d = [b - a for a, b in zip(stamps, stamps[1:])]
    return {
        "n": len(stamps),
        "p50_ms": quantile(d, 0.5) * 1e3,
        "p99_ms": quantile(d, 0.99) * 1e3,
        "max_ms": max(d, default=float("nan")) * 1e3,
        "late": sum(1 for x in d if x > 1.5 * period),
    }


def peer_log(path: str) -> list[dict]:
    out = []
    if os.path.exists(path):
        with open(path, encoding="utf-8") as f:
            for line in f:
                try:
                    out.append(json.loads(line))
                except ValueError:
                    pass
    return out


def wired_losses(rec: dict, logs: str) -> dict:
    """Replies the peers answered vs readings recorded, per channel."""
    table = peer_log(os.path.join(logs, "table.jsonl"))
    chamber = peer_log(os.path.join(logs, "chamber.jsonl"))
    gyro = peer_log(os.path.join(logs, "gyro.jsonl"))
    # The first table and chamber reads are the drivers' connect probes, not polls.
    polls = [e for e in table if str(e.get("rx", "")).startswith("PRV 1,?")
             and "ERR" not in str(e.get("tx", ""))][1:]
    # A chamber poll reads the process value (register 1) then the working set point (5).
    pv_reads = [e for e in chamber if e.get("fc") == 3 and e.get("addr") == 1
                and "exception" not in e][1:]
    sent = [e["sample"] for e in gyro if "sample" in e]
    g_stamps, g_body = rec["channels"]["/gyro/rate"]
    seqs = [b["seq"] for b in g_body]
    in_range = [s for s in sent if seqs and seqs[0] <= s["seq"] <= seqs[-1]]
    gaps = sum(1 for a, b in zip(seqs, seqs[1:]) if b != a + 1)
    out = {
        "/table/state": {"answered": len(polls),
                         "recorded": len(rec["channels"]["/table/state"][0])},
        "/chamber/state": {"answered": len(pv_reads),
                           "recorded": len(rec["channels"]["/chamber/state"][0])},
        "/gyro/rate": {"answered": len(in_range), "recorded": len(g_body), "seq_gaps": gaps},
    }
    for v in out.values():
        v["lost"] = v["answered"] - v["recorded"]
    # Table reply latency: each reading's host stamp against the peer's time of the last
    # request it had received by then (the two clocks aligned by the fastest of the first
    # polls): the time from the peer's answer to the host's stamp, above the fastest one.
    t_stamps = rec["channels"]["/table/state"][0]
    req = [e["t"] for e in polls]
    if polls and t_stamps:
        k = min(len(req), len(t_stamps), 2000)
        offset = min(s - r for s, r in zip(t_stamps[:k], req[:k]))
        lat = []
        for s in t_stamps:
            i = bisect.bisect_right(req, s - offset + 1e-4) - 1
            if i >= 0:
                lat.append(s - offset - req[i])
        out["/table/state"]["latency_ms"] = {
            "p50": quantile(lat, 0.5) * 1e3, "p99": quantile(lat, 0.99) * 1e3,
            "max": max(lat) * 1e3}
    return out


def calibrate(bench: str, rec: str, out: str, t0: float) -> dict:
    """`bench calibrate` at reference temperature `t0`; its JSON whatever the verdict (a poor
    fit or an incomplete calibration exits non-zero but still writes it)."""
    js = f"{out}.json"
    shutil.rmtree(out, ignore_errors=True)
    if os.path.exists(js):
        os.remove(js)
    code = run([bench, "calibrate", rec, "-o", out, "--json", js, "--no-report", "-q",
                "--reference-temperature-c", str(t0)], log=f"{out}.log", ok=range(256))
    if not os.path.exists(js):
        raise SystemExit(f"calibrate {rec} exited {code} without a JSON: see {out}.log")
    with open(js, encoding="utf-8") as f:
        cal = json.load(f)
    cal["exit"] = code
    return cal


def coeff(cal: dict, key: str) -> tuple[float, float]:
    c = cal.get("coefficients", {}).get(key)
    if isinstance(c, dict):
        return c.get("value", float("nan")), c.get("sigma", float("nan"))
    return float("nan"), float("nan")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default=os.path.join(ROOT, "scenarios/seed.toml"))
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--time-scale", type=float, default=1.0)
    p.add_argument("--bench", default=os.path.join(ROOT, "target/release/bench"))
    p.add_argument("--out", default="wired-run")
    p.add_argument("--report-only", action="store_true",
                   help="no runs: report on OUT's recordings and peer logs again")
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    out = lambda name: os.path.join(args.out, name)  # noqa: E731
    inproc = out("inproc.mcap")

    if not args.report_only:
        run([args.bench, "run", args.scenario, "--seed", str(args.seed), "-o", inproc, "-q",
             "--force"], log=out("inproc.log"))
    ref = read(inproc)
    model = {}
    for k, v in ref["meta"].get("bench.gyro_model", {}).items():
        try:
            model[k] = float(v)
        except ValueError:
            pass  # not a coefficient
    site = ref["meta"].get("bench.site", {})
    latitude = float(site.get("latitude_deg", 45.0))
    air0 = ref["channels"]["/chamber/state"][1][0]["temperature"]

    logs = out("peer-logs")
    wall = wired_run(args, out, logs, model, latitude, air0) if not args.report_only else None
    report(args, out, logs, ref, model, wall)


def wired_run(args, out, logs: str, model: dict, latitude: float, air0: float) -> float:
    """Serve the coupled peers and run the scenario on them; the wall time it took, s."""
    os.makedirs(logs, exist_ok=True)
    serve = subprocess.Popen(
        [sys.executable, os.path.join(ROOT, "tests/peers/serve_bench.py"), "--coupled",
         "--time-scale", str(args.time_scale), "--out", out("peer.toml"), "--log-dir", logs,
         "--gyro-model", json.dumps(model), "--latitude-deg", str(latitude),
         "--initial-temp-c", str(air0), "--chamber-tau-s", "120", "--seed", str(args.seed)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    ready = serve.stdout.readline() if serve.stdout else b""
    if not ready:
        raise SystemExit("the peers did not start")
    wall = time.monotonic()
    try:
        run([args.bench, "run", args.scenario, "--bench", out("peer.toml"), "-o",
             out("wired.mcap"), "-q", "--force", "--time-marks-s", "600"], log=out("wired.log"))
    finally:
        wall = time.monotonic() - wall
        if serve.stdin:
            serve.stdin.close()
        serve.wait(timeout=30)
    return wall


def report(args, out, logs: str, ref: dict, model: dict, wall: float | None) -> None:
    """Jitter, losses and the two calibrations, on stdout and in OUT/summary.md."""
    inproc, wired = out("inproc.mcap"), out("wired.mcap")
    rec = {"in-process": ref, "wired": read(wired)}
    took = "" if wall is None else f", {wall / 60:.1f} min of wall time"
    lines = [f"# Wired run: {os.path.basename(args.scenario)}, seed {args.seed}, "
             f"{args.time_scale:g}x{took}", ""]
    lines += ["## Host stamp intervals", "",
              "| run | channel | samples | p50 ms | p99 ms | max ms | late (> 1.5 periods) |",
              "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for name, r in rec.items():
        for ch in CHANNELS:
            j = jitter(r["channels"][ch][0], 0.05)
            lines.append(f"| {name} | `{ch}` | {j['n']} | {j['p50_ms']:.2f} | "
                         f"{j['p99_ms']:.2f} | {j['max_ms']:.1f} | {j['late']} |")
    losses = wired_losses(rec["wired"], logs)
    lines += ["", "## Wired: answered by the peers vs recorded", "",
              "(after the connect probes; a reply that came after the driver's timeout is asked",
              "for again and skipped when it comes: it counts as answered but not recorded, as",
              "does one in flight when the run ended)",
              "",
              "| channel | answered | recorded | lost | notes |",
              "| --- | ---: | ---: | ---: | --- |"]
    for ch, v in losses.items():
        note = ""
        if "seq_gaps" in v:
            note = f"{v['seq_gaps']} counter gap(s)"
        if "latency_ms" in v:
            s = v["latency_ms"]
            note = (f"request to host stamp, above the fastest: p50 {s['p50']:.2f} ms, "
                    f"p99 {s['p99']:.2f} ms, max {s['max']:.0f} ms")
        lines.append(f"| `{ch}` | {v['answered']} | {v['recorded']} | {v['lost']} | {note} |")

    t0 = model.get("reference_temperature", 20.0)
    cals = {name: calibrate(args.bench, path, out(f"cal-{name}"), t0)
            for name, path in (("in-process", inproc), ("wired", wired))}
    lines += ["", "## Calibration", "",
              "| coefficient | truth | in-process ± 1σ | wired ± 1σ | difference / σ |",
              "| --- | ---: | ---: | ---: | ---: |"]
    for k in COEFFS:
        (a, sa), (b, sb) = coeff(cals["in-process"], k), coeff(cals["wired"], k)
        z = (b - a) / math.hypot(sa, sb) if sa > 0 or sb > 0 else float("nan")
        lines.append(f"| {k} | {model.get(k, float('nan')):.4g} | {a:.4g} ± {sa:.2g} | "
                     f"{b:.4g} ± {sb:.2g} | {z:+.2f} |")
    lines += ["", "## Time bases (bench calibrate)", "",
              "| run | channel | source | drift ppm | jitter ms | max late ms | late outliers |",
              "| --- | --- | --- | ---: | ---: | ---: | ---: |"]
    for name, cal in cals.items():
        for tb in cal.get("time_bases", []):
            ms = lambda v: "—" if v is None else f"{v * 1e3:.2f}"  # noqa: E731
            # A counter's rate is seconds per count, not a drift.
            drift = tb.get("drift_ppm") if tb.get("source") == "device_stamps" else None
            ppm = "—" if drift is None else f"{drift:+.2f}"
            late = tb.get("late_outliers")
            lines.append(f"| {name} | `{tb['topic']}` | {tb['source']} | {ppm} | "
                         f"{ms(tb.get('jitter'))} | {ms(tb.get('max_late'))} | "
                         f"{'—' if late is None else late} |")
    for name, cal in cals.items():
        fit = cal.get("fit", {})
        verdict = fit.get("verdict", fit) if isinstance(fit, dict) else fit
        rms = cal.get("whitened_residual_rms") or float("nan")
        lines.append(f"\n{name}: fit {verdict} (exit {cal['exit']}); whitened residual RMS "
                     f"{rms:.3f}; {len(cal.get('windows', []))} record windows")
    text = "\n".join(lines) + "\n"
    with open(out("summary.md"), "w", encoding="utf-8") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
