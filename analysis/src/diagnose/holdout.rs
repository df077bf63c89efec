//! The held-out check: the shape fitted on alternate blocks predicts the others.

use super::*;

/// Held-out check (module docs): combined z of the gain with which the shape fitted on one
/// set of alternate blocks explains the other.
///
/// Blocks alternate on the clock. A term that lives at a few instants on a schedule (the
/// reversals of a time offset, every 720 s) can fall wholly into one set of clock blocks (60 s
/// blocks: 720 s is 12 of them, every reversal lands in the same set). Where the clock's blocks
/// leave either set less than [`HOLDOUT_MIN_SHARE`] of the term's information, the bins on the
/// term's support are placed by the support time before them instead (the time off the support
/// left out, so its instants alternate between the sets whatever their schedule), the others by
/// the clock as before. Where neither does, the support is that of the columns with the design
/// projected out (a rate² term's information lies in the table's rests, where its column is
/// smallest). The choice reads the columns only, never the data.
pub(super) fn holdout_z(
    design: &[Vec<f64>],
    g: &[Vec<f64>],
    y: &[f64],
    bins: &[Bin],
    noise: &BinNoise,
    block_s: f64,
) -> f64 {
    let mag: Vec<f64> = (0..bins.len()).map(|i| g.iter().map(|c| c[i].abs()).sum()).collect();
    let (block, on_support) = holdout_blocks(bins, &mag, block_s);
    // What each set knows of the term: the variance of its coefficients fitted on all bins
    // over that fitted on the set alone (noise model). A set holding less than
    // HOLDOUT_MIN_SHARE of the information is never the fitting set: its fit would be noise of
    // either sign, then "tested" against the other set's full signal.
    let mut cols_all = design.to_vec();
    cols_all.extend(g.iter().cloned());
    let all: Vec<usize> = (0..bins.len()).collect();
    let term_var = |rows: &[usize]| -> Option<f64> {
        let p = Projector::new(&cols_all, rows).ok()?;
        let cov = p.covariance(noise);
        let mut v = 0.0;
        for j in design.len()..cols_all.len() {
            let c = p.kept.iter().position(|&k| k == j)?;
            v += cov[(c, c)];
        }
        Some(v)
    };
    let full_var = term_var(&all);
    let share = |rows: &[usize]| -> f64 {
        match (full_var, term_var(rows)) {
            (Some(f), Some(v)) if v > 0.0 => f / v,
            _ => 0.0,
        }
    };
    // Each set's share, computed once per partition (a fit and its covariance each).
    let shares = |(a, b): &(Vec<usize>, Vec<usize>)| (share(a), share(b));
    let least = |s: (f64, f64)| s.0.min(s.1);
    let on_clock: Vec<f64> = bins.iter().map(Bin::centre_s).collect();
    let mut sets = holdout_sets(&on_clock, block);
    let mut sets_share = shares(&sets);
    if least(sets_share) < HOLDOUT_MIN_SHARE {
        let other = holdout_sets(&on_support, block);
        let other_share = shares(&other);
        if least(other_share) > least(sets_share) {
            (sets, sets_share) = (other, other_share);
        }
    }
    if least(sets_share) < HOLDOUT_MIN_SHARE {
        // The term's information may lie where its columns are small: a rate² term is a
        // constant the bias takes while the table turns, and is known only from the rests.
        // The support of what the design cannot take (the columns with the design projected
        // out) places those bins in both sets.
        if let Ok(pd) = Projector::new(design, &all) {
            let free = pd.orthogonalise(g);
            let mut info = vec![0.0; bins.len()];
            for col in &free {
                for (r, &i) in pd.rows.iter().enumerate() {
                    info[i] += col[r].abs();
                }
            }
            let (block_info, on_info) = holdout_blocks(bins, &info, block_s);
            let other = holdout_sets(&on_info, block_info);
            let other_share = shares(&other);
            if least(other_share) > least(sets_share) {
                (sets, sets_share) = (other, other_share);
            }
        }
    }
    let (a, b) = sets;
    let mut num = 0.0;
    let mut den = 0.0;
    let mut folds = 0;
    for (fit_rows, fit_share, test_rows) in [(&a, sets_share.0, &b), (&b, sets_share.1, &a)] {
        if fit_rows.len() < 10 || test_rows.len() < 10 || fit_share < HOLDOUT_MIN_SHARE {
            continue;
        }
        folds += 1;
        let mut cols = design.to_vec();
        cols.extend(g.iter().cloned());
        let Ok(pf) = Projector::new(&cols, fit_rows) else { continue };
        let beta = pf.beta(y);
        let mut shape = vec![0.0; bins.len()];
        for (c, &j) in pf.kept.iter().enumerate() {
            if j >= design.len() {
                for (i, s) in shape.iter_mut().enumerate() {
                    *s += beta[c] * g[j - design.len()][i];
                }
            }
        }
        let Ok(pt) = Projector::new(design, test_rows) else { continue };
        if let Some(t) = pt.test(&[shape], y, noise) {
            let var = t.cov[(0, 0)];
            if var > 0.0 {
                num += t.theta[0] / var;
                den += 1.0 / var;
            }
        }
    }
    if folds == 0 {
        // The term lives within one set of blocks: held-out blocks cannot judge it.
        f64::NAN
    } else if den > 0.0 {
        num / den.sqrt()
    } else {
        0.0
    }
}

/// The hold-out's blocks for a term of magnitude `mag` per bin ([`holdout_z`]): their length,
/// short enough that both sets see the term — a quarter of the time it is above a tenth of its
/// peak (a warm-up lives in the first few τ), at most `block_s`, at least six bins — and each
/// bin's time on the term's support (its centre less the span of the bins off the support
/// before it).
pub(super) fn holdout_blocks(bins: &[Bin], mag: &[f64], block_s: f64) -> (f64, Vec<f64>) {
    let peak = mag.iter().fold(0.0f64, |m, v| m.max(*v));
    let support: f64 =
        bins.iter().zip(mag).filter(|(_, m)| **m > 0.1 * peak).map(|(b, _)| b.span_s()).sum();
    let bin_s = bins.first().map_or(1.0, Bin::span_s);
    let block_s = (0.25 * support).min(block_s).max(6.0 * bin_s);
    let mut off_s = 0.0;
    let on_support: Vec<f64> = bins
        .iter()
        .zip(mag)
        .map(|(b, m)| {
            if *m > 0.1 * peak {
                b.centre_s() - off_s
            } else {
                off_s += b.span_s();
                b.centre_s()
            }
        })
        .collect();
    (block_s, on_support)
}

/// The bins in even and in odd blocks of `block_s` of their time `clock`.
pub(super) fn holdout_sets(clock: &[f64], block_s: f64) -> (Vec<usize>, Vec<usize>) {
    (0..clock.len()).partition(|&i| ((clock[i] / block_s).floor() as i64).rem_euclid(2) == 0)
}
