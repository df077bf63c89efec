#!/usr/bin/env python3
"""The residual scan of `bench diagnose` written in NumPy, to check it and time it against Rust.

    scripts/diagnose_numpy.py RECORDING.mcap [--bench target/release/bench] [--inputs DIR]
                              [--repeat N] [--recurrence]

The scan (docs/diagnose.md, "Speed"; `residual_scan` in analysis/src/diagnose/mod.rs): every
candidate effect's regressors, binned (dt-weighted means over each bin's samples), tested
against the refitted nominal design at every grid value: G⊥ = G − X·X⁺G, θ = (G⊥ᵀG⊥)⁻¹G⊥ᵀy,
the sandwich covariance V = P·Σ·Pᵀ (P = (G⊥ᵀG⊥)⁻¹G⊥ᵀ, Σ the noise model's covariance of bin
means), W = θᵀV⁻¹θ, ΔRSS = θᵀG⊥ᵀG⊥θ; per effect the grid value with the largest ΔRSS is kept.

What it shares with Rust, read from `bench diagnose --scan-only --scan-inputs DIR`: the
per-sample arrays after loading (time, interval, table angle and settled rate, temperature,
hysteresis state), the bins (sample ranges), the nominal residual of the bins, the nominal
design, the noise model's parameters and the grids — the table-motion fit, the clock model and
the Allan-deviation fit are not written again here. The gyro's samples are read from the MCAP
file with the `mcap` package and checked against the samples the inputs hold. Everything the
scan does from there is NumPy: the regressors, their bin means, the dense Σ, the projections
and the statistics.

The sinusoids (angle harmonics, rate ripple, periodic bias) take one sin and cos per sample
and grid value by default; `--recurrence` computes them as Rust does, by rotation: an exact sin
and cos per sample every 64 grid values, a complex multiplication per sample and value between
(vectorized over the samples), with the same correction of the periods' uneven spacing.

Prints each effect's best grid value, Wald and ΔRSS, the agreement with Rust's scan (same best
grid value, Wald and ΔRSS within a relative 1e-6) and both times. Exit 0 when they agree, 1
when not.
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
REL_TOL = 1e-6


SEQ_GAP = 2  # status bit 1: samples were lost before this one, which is itself valid


def read_gyro(path):
    """The gyro's valid samples from the MCAP file in log-time order, by the loader's rule
    (report/src/load.rs): a finite rate with status 0, or exactly the counter-gap bit on a
    sample whose counter did skip."""
    from mcap.reader import make_reader

    rates = []
    prev_seq = None
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _schema, _channel, message in reader.iter_messages(
            topics=["/gyro/rate"], log_time_order=True
        ):
            m = json.loads(message.data)
            seq, status, rate = m.get("seq"), m.get("status", 0), m.get("rate")
            skipped = prev_seq is not None and seq != (prev_seq + 1) % 2**64
            prev_seq = seq
            valid = status == 0 or (status == SEQ_GAP and skipped)
            if valid and rate is not None and np.isfinite(rate):
                rates.append(rate)
    return np.asarray(rates, dtype=float)


class Inputs:
    def __init__(self, d):
        d = Path(d)
        self.meta = json.loads((d / "scan.json").read_text())
        self.a = {p.stem: np.load(p) for p in d.glob("*.npy")}
        self.s = self.meta["scalars"]


def noise_matrix(inp):
    """Dense covariance of the bins' means under the noise model (white, the flicker's
    Gauss–Markov components integrated over the bins, rate random walk)."""
    a, s = inp.a, inp.s
    start, end = a["bin_start_s"], a["bin_end_s"]
    span, centre = end - start, 0.5 * (start + end)
    sigma = np.diag(s["arw"] ** 2 / span)
    dist = np.abs(centre[:, None] - centre[None, :])
    for t, var in zip(a["noise_t"], a["noise_var"]):
        x = span / t
        within = 2.0 * var / x * (1.0 - (-np.expm1(-x)) / x)
        with np.errstate(over="ignore"):
            g = np.where(x > 40.0, 0.0, 2.0 / x * np.sinh(np.minimum(0.5 * x, 20.0)))
        if not np.any(g != 0.0):
            sigma[np.diag_indices_from(sigma)] += within
            continue
        comp = var * np.outer(g, g) * np.exp(-dist / t)
        comp[np.diag_indices_from(comp)] = within
        sigma += comp
    if s["rrw"] > 0.0:
        sigma += s["rrw"] ** 2 * (np.minimum.outer(centre, centre) - centre[0])
    if "ref_var_angle" in a and len(a["ref_var_angle"]) > 0:
        # The table reference's error: each bin's reference is the step of the steady lines
        # across it, so J (bins x 2 per segment) holds its sensitivity to each line's angle at
        # its mid time and to its rate; D their variances.
        m = len(a["ref_var_angle"])
        jac = np.zeros((len(span), 2 * m))
        rows = np.arange(len(span))
        for end in ("0", "1"):
            seg = a["ref_seg" + end].astype(np.int64)
            np.add.at(jac, (rows, 2 * seg), a["ref_angle" + end])
            np.add.at(jac, (rows, 2 * seg + 1), a["ref_rate" + end])
        d = np.empty(2 * m)
        d[0::2], d[1::2] = a["ref_var_angle"], a["ref_var_rate"]
        sigma += (jac * d) @ jac.T
        if "ref_var_group" in a and len(a["ref_var_group"]) > 0:
            # Rests on one reading, and turning lines of one rate and direction, share a
            # rounding error: J's angle columns summed by group.
            group = a["ref_group"].astype(np.int64)
            jg = np.zeros((len(span), len(a["ref_var_group"])))
            for j in np.nonzero(group >= 0)[0]:
                jg[:, group[j]] += jac[:, 2 * j]
            sigma += (jg * a["ref_var_group"]) @ jg.T
    return sigma


class Binner:
    """dt-weighted means over each bin's sample range."""

    def __init__(self, inp, recurrence=False):
        a = inp.a
        self.recurrence = recurrence
        first = a["bin_first"].astype(np.int64)
        end = a["bin_end"].astype(np.int64)
        self.sel_first_last = (first, end - 1)
        lengths = end - first
        self.idx = np.concatenate([np.arange(f, e) for f, e in zip(first, end)])
        self.starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
        self.dt = a["dt"][self.idx]
        self.wsum = np.add.reduceat(self.dt, self.starts)

    def mean(self, x):
        """Bin means of per-sample columns x (samples × m, already at the bins' samples)."""
        if x.ndim == 1:
            return np.add.reduceat(x * self.dt, self.starts) / self.wsum
        if not x.flags.c_contiguous and x.T.flags.c_contiguous:
            # values × samples in memory (the recurrence's arrays): reduce along the rows.
            return (np.add.reduceat(x.T * self.dt[None, :], self.starts, axis=1) / self.wsum).T
        return np.add.reduceat(x * self.dt[:, None], self.starts, axis=0) / self.wsum[:, None]

    def sel(self, x):
        return x[self.idx]


ANCHOR_EVERY = 64  # grid values per rotation block, as in Rust (analysis/src/diagnose/columns.rs)
CHUNK = 16  # grid values whose per-sample sin and cos are held at once


def rotated_sin_cos(x, w_a, h, steps):
    """sin and cos of (w_a + m·h)·x for m in 0..steps, by rotation (--recurrence): the anchor
    e^{i·w_a·x} and the step e^{i·h·x} from one sin and cos each, then one complex
    multiplication per value, vectorized over the samples. Yields (m, sin, cos) per CHUNK
    values as arrays samples × values (views of values × samples arrays: each value's samples
    contiguous)."""
    z = np.exp(1j * (w_a * x))
    step = np.exp(1j * (h * x))
    for j in range(0, steps, CHUNK):
        n = min(CHUNK, steps - j)
        sn = np.empty((n, len(x)))
        cs = np.empty((n, len(x)))
        for i in range(n):
            sn[i] = z.imag
            cs[i] = z.real
            np.multiply(z, step, out=z)
        yield j, sn.T, cs.T


def rotated_periodic(binner, t, grid):
    """Bin means of sin(2π t/P) and cos(2π t/P) for the periods of an evenly-in-frequency grid,
    by rotation in blocks of ANCHOR_EVERY as Rust does, with the same per-bin correction of the
    frequencies' departure from even spacing (ε·t̄ per value, t̄ the bin's middle time)."""
    w = 2.0 * np.pi / grid
    out = np.empty((len(binner.wsum), len(grid), 2))
    first = binner.sel_first_last
    t_mid = 0.5 * (t[first[0]] + t[first[1]])
    ts = binner.sel(t)
    for b in range(0, len(grid), ANCHOR_EVERY):
        wb = w[b : b + ANCHOR_EVERY]
        n = len(wb)
        h = (wb[-1] - wb[0]) / (n - 1) if n > 1 else 0.0
        eps = (wb - wb[0]) - np.arange(n) * h
        for j, sn, cs in rotated_sin_cos(ts, wb[0], h, n):
            ms, mc = binner.mean(sn), binner.mean(cs)
            d = eps[j : j + sn.shape[1]][None, :] * t_mid[:, None]
            out[:, b + j : b + j + sn.shape[1], 0] = ms + d * mc
            out[:, b + j : b + j + sn.shape[1], 1] = mc - d * ms
    return out


def columns(inp, binner, effect, grid):
    """The candidate's columns at every grid value: array (bins × values × k)."""
    a, s = inp.a, inp.s
    axis, scale, t0, earth_in = s["axis"], s["scale"], s["t0"], s["earth_in"]
    grid = np.asarray([np.nan if g is None else g for g in grid], dtype=float)
    n = len(a["bin_start_s"])
    if effect in ("angle_harmonic", "rate_ripple"):
        # As in Rust, a harmonic and the ripple at the same k share each sample's sin and cos.
        shared = angle_and_ripple(inp, binner)
        ks = [float(k) for k in grid]
        return np.stack([shared[1 if effect == "rate_ripple" else 0][k] for k in ks], axis=1)
    if effect in ("once_per_revolution", "periodic_bias"):
        if effect == "once_per_revolution":
            grid = np.array([1.0])
        if effect == "periodic_bias" and binner.recurrence:
            return rotated_periodic(binner, a["t"], grid)
        out = np.empty((n, len(grid), 2))
        if effect == "periodic_bias":
            arg_base = binner.sel(a["t"])
            mult = 2.0 * np.pi / grid
        else:
            arg_base = binner.sel(a["angle_mid"])
            mult = grid
        chunk = 16
        for j in range(0, len(grid), chunk):
            arg = np.multiply.outer(arg_base, mult[j : j + chunk])
            sn, cs = np.sin(arg), np.cos(arg)
            out[:, j : j + chunk, 0] = binner.mean(sn)
            out[:, j : j + chunk, 1] = binner.mean(cs)
        return out
    if effect == "time_offset":
        return (-scale * axis * a["bin_accel"])[:, None, None]
    if effect == "bias_step":
        return (a["bin_start_s"][:, None] >= grid[None, :]).astype(float)[:, :, None]
    if effect == "thermal_hysteresis":
        return binner.mean(binner.sel(a["hysteresis"]))[:, None, None]
    dtemp = binner.sel(a["temp"]) - t0
    inp_rate = axis * binner.sel(a["table_rate"]) + earth_in
    if effect == "temperature_quadratic":
        return binner.mean(dtemp * dtemp)[:, None, None]
    if effect == "scale_factor_temperature":
        return binner.mean(dtemp * inp_rate)[:, None, None]
    if effect == "rate_squared":
        return binner.mean(inp_rate * inp_rate)[:, None, None]
    if effect == "warm_up":
        t = binner.sel(a["t"])
        return binner.mean(np.exp(-np.divide.outer(t, grid)))[:, :, None]
    if effect == "bias_drift":
        return binner.mean(binner.sel(a["t"]))[:, None, None]
    if effect == "scale_factor_asymmetry":
        return binner.mean(np.abs(inp_rate))[:, None, None]
    raise ValueError(f"no regressor for {effect}")


def angle_and_ripple(inp, binner):
    """Bin means of sin(kθ), cos(kθ) and of axis·Ω_t·sin(kθ), axis·Ω_t·cos(kθ) for every k of
    the angle-harmonic and ripple grids, from one sin and cos per sample and k: two dicts
    k → (bins × 2)."""
    if getattr(binner, "shared", None) is not None:
        return binner.shared
    a, grids = inp.a, inp.meta["grids"]
    ks = sorted(
        {float(k) for e in ("angle_harmonic", "rate_ripple") for k in grids.get(e, [])}
    )
    theta = binner.sel(a["angle_mid"])
    amp = inp.s["axis"] * binner.sel(a["table_rate"])
    angle, ripple = {}, {}
    if binner.recurrence:
        # Integer orders k in blocks ⌊k / ANCHOR_EVERY⌋ anchored at the block's first integer,
        # step e^{iθ} (as Rust).
        blocks = sorted({int(k) // ANCHOR_EVERY for k in ks})
        for blk in blocks:
            k0 = blk * ANCHOR_EVERY
            want = [k for k in ks if int(k) // ANCHOR_EVERY == blk]
            steps = int(max(want)) - k0 + 1
            for j, sn, cs in rotated_sin_cos(theta, float(k0), 1.0, steps):
                ms, mc = binner.mean(sn), binner.mean(cs)
                rs, rc = binner.mean(sn * amp[:, None]), binner.mean(cs * amp[:, None])
                for i in range(sn.shape[1]):
                    k = float(k0 + j + i)
                    if k in want:
                        angle[k] = np.column_stack([ms[:, i], mc[:, i]])
                        ripple[k] = np.column_stack([rs[:, i], rc[:, i]])
        binner.shared = (angle, ripple)
        return binner.shared
    chunk = 16
    for j in range(0, len(ks), chunk):
        kk = np.asarray(ks[j : j + chunk])
        arg = np.multiply.outer(theta, kk)
        sn, cs = np.sin(arg), np.cos(arg)
        ms, mc = binner.mean(sn), binner.mean(cs)
        rs, rc = binner.mean(sn * amp[:, None]), binner.mean(cs * amp[:, None])
        for i, k in enumerate(kk):
            angle[float(k)] = np.column_stack([ms[:, i], mc[:, i]])
            ripple[float(k)] = np.column_stack([rs[:, i], rc[:, i]])
    binner.shared = (angle, ripple)
    return binner.shared


def test_all(g, x, x_pinv, y, sigma):
    """Wald and ΔRSS of every grid value's columns g (bins × values × k) against design x."""
    n, m, k = g.shape
    flat = g.reshape(n, m * k)
    gp = (flat - x @ (x_pinv @ flat)).reshape(n, m, k)
    gtg = np.einsum("nmk,nml->mkl", gp, gp)
    gty = np.einsum("nmk,n->mk", gp, y)
    norm = np.einsum("nmk,nmk->mk", g, g)
    ok = np.all(np.diagonal(gtg, axis1=1, axis2=2) > 1e-12 * norm, axis=1)
    inv = np.linalg.inv(np.where(ok[:, None, None], gtg, np.eye(k)))
    theta = np.einsum("mkl,ml->mk", inv, gty)
    sgp = (sigma @ gp.reshape(n, m * k)).reshape(n, m, k)
    a = np.einsum("nmk,nml->mkl", gp, sgp)
    cov = inv @ a @ inv
    wald = np.einsum("mk,mk->m", theta, np.linalg.solve(cov, theta[:, :, None])[:, :, 0])
    drss = np.einsum("mk,mkl,ml->m", theta, gtg, theta)
    return np.where(ok, wald, np.nan), np.where(ok, drss, np.nan)


def scan(inp, recurrence=False):
    """Each effect's best grid value: {effect: (value, wald, drss, grid values)}; the times of
    the setup (Σ, X⁺, bin index) and of the scan proper."""
    t_setup = time.perf_counter()
    cpu_setup = time.process_time()
    a = inp.a
    sigma = noise_matrix(inp)
    x = np.column_stack([a[f"base_{j}"] for j in range(4) if f"base_{j}" in a])
    x_pinv = np.linalg.pinv(x)
    binner = Binner(inp, recurrence)
    y = a["y"]
    setup_s = time.perf_counter() - t_setup
    t_scan = time.perf_counter()
    cpu_scan = time.process_time()
    best = {}
    for effect, grid in inp.meta["grids"].items():
        g = columns(inp, binner, effect, grid)
        wald, drss = test_all(g, x, x_pinv, y, sigma)
        if np.all(np.isnan(drss)):
            continue
        j = int(np.nanargmax(drss))
        value = grid[j] if effect != "once_per_revolution" else None
        best[effect] = (value, float(wald[j]), float(drss[j]), int(np.sum(~np.isnan(drss))))
    scan_s = time.perf_counter() - t_scan
    cpu_all = time.process_time() - cpu_setup
    return best, setup_s, scan_s, time.process_time() - cpu_scan, cpu_all


def close(a, b):
    return abs(a - b) <= REL_TOL * max(abs(a), abs(b), 1e-300)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recording", type=Path)
    ap.add_argument("--bench", type=Path, default=ROOT / "target/release/bench")
    ap.add_argument(
        "--inputs", type=Path, help="inputs already written by `bench diagnose --scan-only`"
    )
    ap.add_argument("--repeat", type=int, default=1, help="time the scan this many times (min)")
    ap.add_argument(
        "--recurrence",
        action="store_true",
        help="the sinusoids by the rotation recurrence Rust uses (an exact sin and cos per "
        f"sample every {ANCHOR_EVERY} grid values, complex multiplications between, vectorized "
        "over the samples) instead of a sin and cos per sample and grid value",
    )
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        inputs = args.inputs
        if inputs is None:
            inputs = Path(tmp) / "inputs"
            cmd = [str(args.bench), "diagnose", str(args.recording), "--scan-only", "-q"]
            subprocess.run(cmd + ["--scan-inputs", str(inputs)], check=True)
        inp = Inputs(inputs)

    t = time.perf_counter()
    rates = read_gyro(args.recording)
    read_s = time.perf_counter() - t
    v = inp.a["v"]
    same_samples = len(rates) == len(v) and np.array_equal(rates, v)
    print(
        f"gyro samples read with mcap: {len(rates)} in {read_s:.2f} s; "
        f"{'equal to' if same_samples else 'DIFFERENT from'} the scan's {len(v)} samples"
    )

    runs = [scan(inp, args.recurrence) for _ in range(max(1, args.repeat))]
    best, setup_s, scan_s, cpu_s, cpu_all = min(runs, key=lambda r: r[2])
    rust = inp.meta["result"]
    rust_best = {b["effect"]: b for b in rust["best"]}
    ok = same_samples and set(best) == set(rust_best)
    print("| effect | grid values | best value | Wald (NumPy) | Wald (Rust) | ΔRSS rel. diff | agree |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for effect, (value, wald, drss, m) in best.items():
        r = rust_best.get(effect)
        agree = (
            r is not None
            and r["grid_values"] == m
            and (r["value"] == value or (r["value"] is None and value is None))
            and close(r["wald"], wald)
            and close(r["delta_rss"], drss)
        )
        ok &= agree
        rel = abs(drss - r["delta_rss"]) / max(abs(drss), 1e-300) if r else float("nan")
        shown = "—" if value is None else f"{value:.6g}"
        rust_w = f"{r['wald']:.6f}" if r else "—"
        print(
            f"| {effect} | {m} | {shown} | {wald:.6f} | {rust_w} | {rel:.1e} | "
            f"{'yes' if agree else 'NO'} |"
        )
    rust_scan = rust["time_s"]["scan"]
    print(
        f"NumPy ({'rotation recurrence' if args.recurrence else 'sin and cos per value'}): "
        f"setup (Σ, X⁺, bin index) {setup_s:.3f} s, scan {scan_s:.3f} s (CPU {cpu_s:.3f} s; "
        f"best of {len(runs)}); Rust scan {rust_scan:.3f} s on {rust['threads']} thread(s) "
        f"({rust['bins']} bins, {rust['samples']} samples)"
    )
    print(f"ratio NumPy/Rust on the scan (wall): {scan_s / rust_scan:.1f}x")
    rust_cpu = rust.get("cpu_s_prepare_and_scan")
    if rust_cpu:
        print(
            f"CPU, every thread: NumPy setup and scan {cpu_all:.2f} s, Rust prepare and scan "
            f"{rust_cpu:.2f} s: ratio {cpu_all / rust_cpu:.1f}x"
        )
    print("agree" if ok else "DISAGREE")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
