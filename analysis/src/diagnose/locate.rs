//! Where the residual departs from the noise model, and what is left unexplained.

use super::*;

/// The run's first-message-relative span where a contribution exceeds half its peak.
pub(super) fn windows_of(bins: &[Bin], contribution: &[f64]) -> Vec<(f64, f64)> {
    let peak = contribution.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if peak == 0.0 {
        return Vec::new();
    }
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (b, c) in bins.iter().zip(contribution) {
        if c.abs() >= 0.5 * peak {
            match out.last_mut() {
                Some(last) if b.start_s - last.1 <= 60.0 => last.1 = b.end_s,
                _ => out.push((b.start_s, b.end_s)),
            }
        }
    }
    out.truncate(20);
    out
}

/// Mean of `r` over bins `idx` and its σ under the noise model.
pub(super) fn region(name: String, idx: &[usize], r: &[f64], noise: &BinNoise) -> Option<Region> {
    if idx.is_empty() {
        return None;
    }
    let w_each = 1.0 / idx.len() as f64;
    let mut w = vec![0.0; r.len()];
    for &i in idx {
        w[i] = w_each;
    }
    let mean = idx.iter().map(|&i| r[i]).sum::<f64>() * w_each;
    Some(Region { name, bins: idx.len(), mean, sigma: noise.quad(&w, &w).sqrt() })
}

/// Location of the residual (module docs, step 5).
pub(super) fn locate(
    prep: &Prepared,
    run: &RunSeries,
    r: &[f64],
    noise: &BinNoise,
    proj: &Projector,
    y: &[f64],
) -> Location {
    let bins = &prep.bins;
    let n = bins.len();
    let dt = &prep.native.dt;
    let mut loc = Location::default();
    for s in &run.steps {
        let idx: Vec<usize> = (0..n)
            .filter(|&i| bins[i].centre_s() >= s.start_s && bins[i].centre_s() < s.end_s)
            .collect();
        let name = if s.label.is_empty() { s.name.clone() } else { s.label.clone() };
        if let Some(reg) = region(format!("#{} {name}", s.index), &idx, r, noise) {
            loc.steps.push(reg);
        }
    }
    let by = |f: &dyn Fn(usize) -> bool| -> Vec<usize> { (0..n).filter(|&i| f(i)).collect() };
    let rate = |i: usize| bins[i].table_rate_rad_s;
    for (name, idx) in [
        ("cw", by(&|i| rate(i) < -1e-6)),
        ("ccw", by(&|i| rate(i) > 1e-6)),
        ("rest", by(&|i| rate(i).abs() <= 1e-6)),
    ] {
        if let Some(reg) = region(name.into(), &idx, r, noise) {
            loc.direction.push(reg);
        }
    }
    let tr = bin_mean(bins, dt, |k| prep.temp_rate[k]);
    let thr = HYST_C_S;
    for (name, idx) in [
        ("heating", by(&|i| tr[i] > thr)),
        ("cooling", by(&|i| tr[i] < -thr)),
        ("steady", by(&|i| tr[i].abs() <= thr)),
    ] {
        if let Some(reg) = region(name.into(), &idx, r, noise) {
            loc.thermal.push(reg);
        }
    }
    let tm = bin_mean(bins, dt, |k| prep.temp[k]);
    let lo = tm.iter().fold(f64::INFINITY, |a, b| a.min(*b));
    let hi = tm.iter().fold(f64::NEG_INFINITY, |a, b| a.max(*b));
    if lo.is_finite() && hi.is_finite() {
        let mut band = (lo / 10.0).floor() * 10.0;
        while band < hi {
            let idx = by(&|i| tm[i] >= band && tm[i] < band + 10.0);
            if let Some(reg) = region(format!("{band:.0}..{:.0} °C", band + 10.0), &idx, r, noise)
            {
                loc.temperature.push(reg);
            }
            band += 10.0;
        }
    }
    let ang = bin_mean(bins, dt, |k| prep.native.angle_mid_rad[k]);
    for s in 0..8 {
        let (a0, a1) = (s as f64 * 45.0, (s + 1) as f64 * 45.0);
        let idx = by(&|i| {
            let d = ang[i].to_degrees().rem_euclid(360.0);
            rate(i).abs() > 1e-6 && d >= a0 && d < a1
        });
        if let Some(reg) = region(format!("angle {a0:.0}..{a1:.0}°"), &idx, r, noise) {
            loc.angle.push(reg);
        }
    }
    loc.transitions = region("table accelerations".into(), &by(&|i| bins[i].transition), r, noise);
    // Change point: the bias-step scan.
    let mut best: Option<(f64, f64)> = None;
    for p in grid(prep, EffectId::BiasStep) {
        let cols = vec![bins.iter().map(|b| if b.start_s >= p { 1.0 } else { 0.0 }).collect()];
        if let Some(t) = proj.test(&cols, y, noise) {
            if best.is_none_or(|b| t.wald > b.1) {
                best = Some((p, t.wald));
            }
        }
    }
    loc.change_point = best;
    for h in [1u32, 2] {
        let sc = prep.sinusoid(columns::Kind::Angle, f64::from(h));
        if let Some(t) = proj.test(&sc, y, noise) {
            loc.harmonics.push((h, t.theta[0].hypot(t.theta[1]), t.wald));
        }
    }
    loc
}

/// Blocks of the final residual that depart from the noise model (module docs).
pub(super) fn unexplained(
    prep: &Prepared,
    r: &[f64],
    noise: &BinNoise,
    opts: &DiagnoseOptions,
) -> Vec<Unexplained> {
    let bins = &prep.bins;
    let block = opts.holdout_block_s;
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    let mut cur_key = i64::MIN;
    for (i, bin) in bins.iter().enumerate() {
        let key = (bin.centre_s() / block).floor() as i64;
        if key != cur_key {
            blocks.push(Vec::new());
            cur_key = key;
        }
        if let Some(b) = blocks.last_mut() {
            b.push(i);
        }
    }
    let nb = blocks.len().max(1) as f64;
    let z_thr = normal_quantile(1.0 - opts.alpha / (2.0 * nb));
    let mut windows: Vec<(f64, f64)> = Vec::new();
    let mut flagged: Vec<usize> = Vec::new();
    for b in &blocks {
        if b.len() < 3 {
            continue;
        }
        if let Some(reg) = region(String::new(), b, r, noise) {
            if reg.z().abs() > z_thr {
                let (s, e) = (bins[b[0]].start_s, bins[b[b.len() - 1]].end_s);
                match windows.last_mut() {
                    Some(last) if s - last.1 <= 1.0 => last.1 = e,
                    _ => windows.push((s, e)),
                }
                flagged.extend(b.iter().copied());
            }
        }
    }
    if windows.is_empty() {
        return Vec::new();
    }
    let dt = &prep.native.dt;
    let signals: Vec<(&str, Vec<f64>)> = vec![
        ("temperature", bin_mean(bins, dt, |k| prep.temp[k])),
        ("temperature rate", bin_mean(bins, dt, |k| prep.temp_rate[k])),
        ("table rate", bins.iter().map(|b| b.table_rate_rad_s).collect()),
        ("|table rate|", bins.iter().map(|b| b.table_rate_rad_s.abs()).collect()),
        ("time", bins.iter().map(Bin::centre_s).collect()),
    ];
    let corr = |a: &[f64], b: &[f64]| {
        let m = a.len() as f64;
        let (ma, mb) = (a.iter().sum::<f64>() / m, b.iter().sum::<f64>() / m);
        let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
        for (x, y) in a.iter().zip(b) {
            sab += (x - ma) * (y - mb);
            saa += (x - ma) * (x - ma);
            sbb += (y - mb) * (y - mb);
        }
        if saa > 0.0 && sbb > 0.0 {
            sab / (saa * sbb).sqrt()
        } else {
            0.0
        }
    };
    let (name, c) = signals
        .iter()
        .map(|(name, s)| (*name, corr(r, s)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or(("nothing", 0.0));
    let sel: Vec<f64> = flagged.iter().map(|&i| r[i]).collect();
    vec![Unexplained {
        windows_s: windows,
        correlates_with: format!("{name} (r = {c:.2})"),
        rms: rms(&sel),
    }]
}
