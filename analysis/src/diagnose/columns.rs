//! The sinusoidal regressors of the search, computed once per run and in parallel.
//!
//! The angle harmonics, the table's rate ripple and the periodic bias are bin means of
//! `sin`/`cos` over every gyro sample (a 5 h 20 Hz run: 366 k samples per column, ~900 columns
//! over the grids and the family checks). They depend on the run and the grid value only, so
//! each is computed once ([`ColumnMemo`]) and shared by the search, the refinements, the family
//! check, the location and the rate-dependence test. An angle harmonic and the ripple at the
//! same `k` share each sample's `sin(k·θ)` and `cos(k·θ)` (one pass for both).
//!
//! **Whole grids by rotation** ([`ColumnMemo::prefill`]). The grids are evenly spaced in the
//! sinusoid's angular multiplier: the angle orders are integers (`e^{i(k+1)θ} = e^{ikθ}·e^{iθ}`)
//! and the periodic bias's periods are evenly spaced in frequency
//! (`e^{iw_{j+1}t} = e^{iw_j t}·e^{i·Δw·t}`). So a block of [`ANCHOR_EVERY`] grid values costs
//! each sample one `sin_cos` (the block's first value, its anchor) and one complex
//! multiplication per value, instead of one `sin_cos` per value; the step (`e^{iθ}`, or
//! `e^{i·Δw·t}` with Δw from the grid's first and last frequencies) is one more `sin_cos` per
//! sample for a whole grid (and is the anchor of the angle orders' first block, 1..64). The
//! blocks are fixed by the values alone (angle order `k ≥ 1` in block `⌊(k − 1) / ANCHOR_EVERY⌋`,
//! anchored at its first integer; the periods by their position in the grid), and the parallel
//! work items are a grid over runs of [`BIN_RUN`] bins (a bin's means depend on its own samples
//! only), never chosen by the number of threads: the columns are bit for bit the same whichever
//! number of threads.
//!
//! A rotated column is not bit for bit the direct [`super::series::bin_mean`] of `sin(w·x)`: it
//! differs by rounding. The periods' angular frequencies `2π/P` are evenly spaced only to a few
//! ulp; what the constant step leaves (`ε_j = w_j − w_a − m·Δw`, ~1e-17 rad/s on a 5 h
//! run, up to 2.5e-13 rad of phase at its end) is put back per bin as a rotation of the bin's
//! sums by `ε_j·x̄` (x̄ the middle of the bin's `x`; within the bin the rest is below 1e-16
//! rad). Measured against the direct computation, as the largest absolute difference of a
//! unit sinusoid's bin mean (the ripple's relative to its amplitude): on the lab writer's 5 h
//! `lab-null` file 1.4e-14 (angle), 2.1e-15 (ripple), 2.7e-14 (periodic; 2.4e-13 without the
//! correction); on the unit test's synthetic run (`rotated_grid_agrees_with_sin_cos`, bound
//! 1e-13) 1.3e-14, 1.3e-14, 2.7e-14. Most of it is the direct computation's own rounding of the
//! argument `w·x` (half an ulp of ~960 rad is 5.7e-14 rad at the run's end). Values requested
//! one at a time (refinements, family members off the grids) are computed directly, bit for bit
//! as `bin_mean` of the same expression; a value already in the memo is never recomputed, so
//! every use of a regressor within a run sees the same bits.

use std::collections::HashMap;
use std::sync::Mutex;

use super::series::{Bin, Native};

/// Which sinusoidal regressor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(super) enum Kind {
    /// `sin(k·θ)`, `cos(k·θ)`: the gyro's angle harmonic k (θ the table angle).
    Angle,
    /// `axis·Ω_t·sin(k·θ)`, `axis·Ω_t·cos(k·θ)`: the table's rate ripple at k.
    Ripple,
    /// `sin(2π·t/P)`, `cos(2π·t/P)`: a periodic bias of period P.
    Periodic,
}

/// A regressor's key: its kind and grid value (the value's bits).
type Key = (Kind, u64);
/// A regressor's columns (sin, cos), each a bin mean per bin.
type Columns = Vec<Vec<f64>>;

/// Columns already computed, by kind and grid value.
#[derive(Debug, Default)]
pub(super) struct ColumnMemo(Mutex<HashMap<Key, Columns>>);

impl ColumnMemo {
    /// The two columns (sin, cos) of `kind` at `p`, computed once.
    pub(super) fn get(
        &self,
        native: &Native,
        bins: &[Bin],
        axis: f64,
        kind: Kind,
        p: f64,
    ) -> Vec<Vec<f64>> {
        if let Some(c) = self.lock().get(&(kind, p.to_bits())) {
            return c.clone();
        }
        // Computed outside the lock: another thread may compute the same columns meanwhile,
        // to the same bits.
        let computed: Vec<(Key, Columns)> = match kind {
            Kind::Periodic => vec![((kind, p.to_bits()), periodic(native, bins, p))],
            Kind::Angle | Kind::Ripple => {
                let (angle, ripple) = angle_and_ripple(native, bins, axis, p);
                vec![((Kind::Angle, p.to_bits()), angle), ((Kind::Ripple, p.to_bits()), ripple)]
            }
        };
        let mut memo = self.lock();
        let mut out = Vec::new();
        for (key, cols) in computed {
            if key.0 == kind {
                out.clone_from(&cols);
            }
            memo.entry(key).or_insert(cols);
        }
        out
    }

    /// Prefill with whole grids, computed by rotation ([module docs](self)) in parallel: the
    /// angle harmonic and the ripple at every order of `angle_orders`, and the periodic bias
    /// at every period of `periods` (a grid evenly spaced in frequency, in its order). Values
    /// already memoized are kept; a value that is not on an evenly spaced grid (a non-integer
    /// order, a period off the frequency spacing) is computed directly.
    pub(super) fn prefill(
        &self,
        native: &Native,
        bins: &[Bin],
        axis: f64,
        angle_orders: &[f64],
        periods: &[f64],
        n_threads: usize,
    ) {
        self.prefill_on(native, bins, axis, angle_orders, periods, n_threads);
    }

    /// [`Self::prefill`] on `n_threads` threads.
    fn prefill_on(
        &self,
        native: &Native,
        bins: &[Bin],
        axis: f64,
        angle_orders: &[f64],
        periods: &[f64],
        n_threads: usize,
    ) {
        let tasks: Vec<Task> = {
            let memo = self.lock();
            plan(angle_orders, periods, native)
                .into_iter()
                .filter(|task| task.keys().iter().any(|key| !memo.contains_key(key)))
                .collect()
        };
        // Each task over runs of BIN_RUN bins (a bin's means do not depend on the others), so
        // that the threads share the blocks evenly; the runs' columns joined in order.
        let items: Vec<(usize, std::ops::Range<usize>)> = tasks
            .iter()
            .enumerate()
            .flat_map(|(i, _)| {
                (0..bins.len()).step_by(BIN_RUN).map(move |a| (i, a..(a + BIN_RUN).min(bins.len())))
            })
            .collect();
        let computed =
            par_map(n_threads, &items, |(i, r)| tasks[*i].compute(native, &bins[r.clone()], axis));
        let mut joined: Vec<Vec<(Key, Columns)>> = tasks.iter().map(|_| Vec::new()).collect();
        for ((i, _), part) in items.iter().zip(computed) {
            let whole = &mut joined[*i];
            if whole.is_empty() {
                *whole = part;
                continue;
            }
            for ((_, cols), (_, more)) in whole.iter_mut().zip(part) {
                for (col, m) in cols.iter_mut().zip(more) {
                    col.extend(m);
                }
            }
        }
        let mut memo = self.lock();
        for (key, cols) in joined.into_iter().flatten() {
            memo.entry(key).or_insert(cols);
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<Key, Columns>> {
        // A panic elsewhere cannot leave a half-written entry: entries are inserted whole.
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// Grid values per rotation block: each block starts from an exact `sin_cos` (its anchor).
/// The rotation's rounding grows with the steps from the anchor (each step's `sin_cos(h·x)`
/// rounding, `h·x ≤ π`, repeats: ≲ 64 · 3e-16 here), but on the lab writer's 5 h file the
/// largest error of a periodic column's bin mean was the same at 8, 16, 32 and 64 (2.7e-14 to
/// 3.2e-14: the anchors' own rounding dominates), 4.6e-14 at 128; the scan's CPU time fell
/// from 0.70 s (8) to 0.46 s (16), 0.36 s (32) and 0.30 s (64, one thread, each block then
/// with its own step; one step shared by a grid's blocks: 0.27 s).
pub(super) const ANCHOR_EVERY: usize = 64;

/// Bins per parallel work item of a prefill (fixed: the work items do not depend on the number
/// of threads).
const BIN_RUN: usize = 128;

/// Samples rotated side by side: independent multiplication chains, so the rotation is not
/// bound by one multiplication's latency.
const LANES: usize = 4;

/// Relative deviation of a grid from even spacing tolerated in a rotation block, as phase at the
/// run's largest `|x|` (rad): the block's per-bin correction is first order in it.
const SPACING_TOL_RAD: f64 = 1e-11;

/// A piece of a prefill: rotation blocks sharing one step, or a single value computed directly.
#[derive(Debug)]
enum Task {
    /// `sin`/`cos` of `w·θ` (and the ripple) for [`Kind::Angle`], of `w·t` for
    /// [`Kind::Periodic`], at every value of `blocks`, all with the step `h`.
    Rotated { kind: Kind, h: f64, blocks: Vec<Block> },
    /// One value computed directly (as [`ColumnMemo::get`] does).
    Direct { kind: Kind, value: f64 },
}

/// Grid values computed from one anchor.
#[derive(Debug)]
struct Block {
    /// The anchor's multiplier of `x`.
    w_a: f64,
    /// `(value, m, eps)`: the value's multiplier is `w_a + m·h + eps`.
    values: Vec<(f64, usize, f64)>,
}

impl Task {
    /// The memo keys this task fills.
    fn keys(&self) -> Vec<Key> {
        let both = |kind: Kind, v: f64| match kind {
            Kind::Periodic => vec![(Kind::Periodic, v.to_bits())],
            Kind::Angle | Kind::Ripple => {
                vec![(Kind::Angle, v.to_bits()), (Kind::Ripple, v.to_bits())]
            }
        };
        match self {
            Task::Rotated { kind, blocks, .. } => blocks
                .iter()
                .flat_map(|b| &b.values)
                .flat_map(|&(v, _, _)| both(*kind, v))
                .collect(),
            Task::Direct { kind, value } => both(*kind, *value),
        }
    }

    /// The task's columns over `bins` (each bin's means depend on its own samples only).
    fn compute(&self, nat: &Native, bins: &[Bin], axis: f64) -> Vec<(Key, Columns)> {
        match self {
            Task::Direct { kind: Kind::Periodic, value } => {
                vec![((Kind::Periodic, value.to_bits()), periodic(nat, bins, *value))]
            }
            Task::Direct { value, .. } => {
                let (angle, ripple) = angle_and_ripple(nat, bins, axis, *value);
                vec![
                    ((Kind::Angle, value.to_bits()), angle),
                    ((Kind::Ripple, value.to_bits()), ripple),
                ]
            }
            Task::Rotated { kind: Kind::Periodic, h, blocks } => {
                let cols = rotated::<false>(&nat.t, &nat.dt, &[], bins, *h, blocks);
                let values = blocks.iter().flat_map(|b| &b.values);
                values
                    .zip(cols)
                    .map(|(&(v, _, _), [s, c, _, _])| ((Kind::Periodic, v.to_bits()), vec![s, c]))
                    .collect()
            }
            Task::Rotated { h, blocks, .. } => {
                let amp: Vec<f64> = nat.table_rate_rad_s.iter().map(|r| axis * r).collect();
                let cols = rotated::<true>(&nat.angle_mid_rad, &nat.dt, &amp, bins, *h, blocks);
                let values = blocks.iter().flat_map(|b| &b.values);
                values
                    .zip(cols)
                    .flat_map(|(&(v, _, _), [s, c, rs, rc])| {
                        [
                            ((Kind::Angle, v.to_bits()), vec![s, c]),
                            ((Kind::Ripple, v.to_bits()), vec![rs, rc]),
                        ]
                    })
                    .collect()
            }
        }
    }
}

/// The prefill's tasks ([module docs](self)): the angle orders by blocks of integers, the
/// periods by blocks of grid positions, each kind's blocks sharing one step; whatever cannot be
/// rotated, directly.
fn plan(angle_orders: &[f64], periods: &[f64], nat: &Native) -> Vec<Task> {
    let mut tasks = Vec::new();
    // Angle orders: integer k ≥ 1 in block ⌊(k − 1) / B⌋, anchored at the block's first integer
    // (the first block's anchor is the step, e^{iθ}).
    let mut orders: Vec<f64> = angle_orders.to_vec();
    orders.sort_by(f64::total_cmp);
    orders.dedup_by(|a, b| a.to_bits() == b.to_bits());
    let mut blocks: std::collections::BTreeMap<u64, Vec<(f64, usize, f64)>> = Default::default();
    let b_len = ANCHOR_EVERY as u64;
    for k in orders {
        if k.fract() == 0.0 && (1.0..=1e6).contains(&k) {
            let ki = k as u64;
            let b = (ki - 1) / b_len;
            blocks.entry(b).or_default().push((k, (ki - 1 - b * b_len) as usize, 0.0));
        } else {
            tasks.push(Task::Direct { kind: Kind::Angle, value: k });
        }
    }
    if !blocks.is_empty() {
        let blocks =
            blocks.into_iter().map(|(b, values)| Block { w_a: (b * b_len + 1) as f64, values });
        tasks.push(Task::Rotated { kind: Kind::Angle, h: 1.0, blocks: blocks.collect() });
    }
    // Periods: blocks of B grid positions, one step from the grid's first and last values; a
    // value off the even spacing (beyond SPACING_TOL_RAD of phase) directly.
    let w: Vec<f64> = periods.iter().map(|p| std::f64::consts::TAU / p).collect();
    let n = w.len();
    let h = if n > 1 { (w[n - 1] - w[0]) / (n - 1) as f64 } else { 0.0 };
    let x_max = nat.t.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut blocks = Vec::new();
    for (b, (block, wb)) in periods.chunks(ANCHOR_EVERY).zip(w.chunks(ANCHOR_EVERY)).enumerate() {
        let w_a = wb[0];
        let mut values = Vec::new();
        for (m, (&p, &wj)) in block.iter().zip(wb).enumerate() {
            let eps = (wj - w_a) - m as f64 * h;
            if w_a.is_finite() && h.is_finite() && (eps * x_max).abs() <= SPACING_TOL_RAD {
                values.push((p, m, eps));
            } else {
                tasks.push(Task::Direct { kind: Kind::Periodic, value: p });
            }
        }
        debug_assert!(b * ANCHOR_EVERY < n);
        if !values.is_empty() {
            blocks.push(Block { w_a, values });
        }
    }
    if !blocks.is_empty() {
        tasks.push(Task::Rotated { kind: Kind::Periodic, h, blocks });
    }
    tasks
}

/// Bin means of `sin(w·x)`, `cos(w·x)` (and with `RIPPLE`, of `amp·sin(w·x)`,
/// `amp·cos(w·x)`) for each `(_, m, eps)` of each block, `w = w_a + m·h + eps`: per sample,
/// the step `e^{i·h·x}` and each block's anchor `e^{i·w_a·x}` from `sin_cos`, then `m`
/// rotations; `eps` (a grid's departure from even spacing, tiny) as a rotation of each bin's
/// sums by `eps·x̄`, x̄ the middle of the bin's `x`. Returns `[sin, cos, amp·sin, amp·cos]` per
/// value in the blocks' order (the last two empty without `RIPPLE`).
fn rotated<const RIPPLE: bool>(
    x: &[f64],
    dt: &[f64],
    amp: &[f64],
    bins: &[Bin],
    h: f64,
    blocks: &[Block],
) -> Vec<[Vec<f64>; 4]> {
    let width = if RIPPLE { 4 } else { 2 };
    // Each block's steps (rows of sums) and its first row.
    let steps: Vec<usize> =
        blocks.iter().map(|b| b.values.iter().map(|v| v.1).max().map_or(0, |m| m + 1)).collect();
    let starts: Vec<usize> = steps
        .iter()
        .scan(0, |acc, &s| {
            let start = *acc;
            *acc += s;
            Some(start)
        })
        .collect();
    let rows = steps.iter().sum::<usize>();
    // Per row: `width` sums, each over LANES lanes.
    let mut acc = vec![[0.0f64; LANES]; rows * width];
    let n_values = blocks.iter().map(|b| b.values.len()).sum();
    let mut out: Vec<[Vec<f64>; 4]> = (0..n_values)
        .map(|_| {
            std::array::from_fn(
                |q| if q < width { Vec::with_capacity(bins.len()) } else { Vec::new() },
            )
        })
        .collect();
    for b in bins {
        acc.iter_mut().for_each(|a| *a = [0.0; LANES]);
        let sw: f64 = dt[b.first..b.end].iter().sum();
        let mut i = b.first;
        while i < b.end {
            // Lanes past the bin's end repeat its last sample with zero weight.
            let mut d = [0.0; LANES];
            let mut a = [0.0; LANES];
            let (mut sr, mut si) = ([0.0; LANES], [0.0; LANES]);
            let mut xs = [0.0; LANES];
            for l in 0..LANES {
                let k = (i + l).min(b.end - 1);
                if i + l < b.end {
                    d[l] = dt[k];
                    if RIPPLE {
                        a[l] = amp[k] * dt[k];
                    }
                }
                xs[l] = x[k];
                (si[l], sr[l]) = (h * x[k]).sin_cos();
            }
            for ((block, &start), &n) in blocks.iter().zip(&starts).zip(&steps) {
                let (mut zr, mut zi) = (sr, si);
                if block.w_a.to_bits() != h.to_bits() {
                    for l in 0..LANES {
                        (zi[l], zr[l]) = (block.w_a * xs[l]).sin_cos();
                    }
                }
                for row in acc[start * width..(start + n) * width].chunks_exact_mut(width) {
                    for l in 0..LANES {
                        row[0][l] += zi[l] * d[l];
                        row[1][l] += zr[l] * d[l];
                        if RIPPLE {
                            row[2][l] += zi[l] * a[l];
                            row[3][l] += zr[l] * a[l];
                        }
                    }
                    for l in 0..LANES {
                        let re = zr[l] * sr[l] - zi[l] * si[l];
                        let im = zr[l] * si[l] + zi[l] * sr[l];
                        (zr[l], zi[l]) = (re, im);
                    }
                }
            }
            i += LANES;
        }
        let x_mid = 0.5 * (x[b.first] + x[b.end - 1]);
        let values =
            blocks.iter().zip(&starts).flat_map(|(bl, &s)| bl.values.iter().map(move |v| (s, v)));
        for (cols, (start, &(_, m, eps))) in out.iter_mut().zip(values) {
            let row = &acc[(start + m) * width..(start + m + 1) * width];
            let mut sums = [0.0; 4];
            for (s, lanes) in sums.iter_mut().zip(row) {
                *s = lanes.iter().sum();
            }
            if eps != 0.0 {
                // sin(φ + δ) = sin φ + δ·cos φ, cos(φ + δ) = cos φ − δ·sin φ (δ ≲ 1e-11).
                let delta = eps * x_mid;
                let [s, c, rs, rc] = sums;
                sums = [s + delta * c, c - delta * s, rs + delta * rc, rc - delta * rs];
            }
            for (col, s) in cols.iter_mut().zip(sums).take(width) {
                col.push(s / sw);
            }
        }
    }
    out
}

/// `bin_mean` of `sin(w·t)` and `cos(w·t)`, `w = 2π/P`.
fn periodic(nat: &Native, bins: &[Bin], period_s: f64) -> Vec<Vec<f64>> {
    let w = std::f64::consts::TAU / period_s;
    let (mut s, mut c) = (Vec::with_capacity(bins.len()), Vec::with_capacity(bins.len()));
    for b in bins {
        let (mut ss, mut sc, mut sw) = (0.0, 0.0, 0.0);
        for k in b.first..b.end {
            let d = nat.dt[k];
            ss += (w * nat.t[k]).sin() * d;
            sc += (w * nat.t[k]).cos() * d;
            sw += d;
        }
        s.push(ss / sw);
        c.push(sc / sw);
    }
    vec![s, c]
}

/// `bin_mean` of `sin(k·θ)`, `cos(k·θ)` (the angle harmonic) and of `axis·Ω_t·sin(k·θ)`,
/// `axis·Ω_t·cos(k·θ)` (the rate ripple) in one pass.
fn angle_and_ripple(
    nat: &Native,
    bins: &[Bin],
    axis: f64,
    k: f64,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = bins.len();
    let mut cols: [Vec<f64>; 4] = std::array::from_fn(|_| Vec::with_capacity(n));
    let (th, tr) = (&nat.angle_mid_rad, &nat.table_rate_rad_s);
    for b in bins {
        let mut sums = [0.0; 4];
        let mut sw = 0.0;
        for i in b.first..b.end {
            let d = nat.dt[i];
            let (sv, cv) = ((k * th[i]).sin(), (k * th[i]).cos());
            sums[0] += sv * d;
            sums[1] += cv * d;
            sums[2] += axis * tr[i] * sv * d;
            sums[3] += axis * tr[i] * cv * d;
            sw += d;
        }
        for (col, s) in cols.iter_mut().zip(sums) {
            col.push(s / sw);
        }
    }
    let [s, c, rs, rc] = cols;
    (vec![s, c], vec![rs, rc])
}

/// `f` over `items` on up to `n_threads` threads, results in order (each item computed as it
/// would be alone: the results do not depend on the number of threads). Items are dealt out in
/// turn (thread `t` takes items `t`, `t + T`, …), so neighbouring items of unequal cost — a
/// grid's expensive columns next to a cheap grid — are shared evenly.
pub(super) fn par_map<T: Sync, R: Send>(
    n_threads: usize,
    items: &[T],
    f: impl Fn(&T) -> R + Sync,
) -> Vec<R> {
    let n_threads = n_threads.min(items.len());
    if n_threads <= 1 {
        return items.iter().map(&f).collect();
    }
    let parts: Vec<Vec<R>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..n_threads)
            .map(|t| {
                let f = &f;
                s.spawn(move || items.iter().skip(t).step_by(n_threads).map(f).collect::<Vec<R>>())
            })
            .collect();
        handles
            .into_iter()
            .map(|h| match h.join() {
                Ok(v) => v,
                Err(e) => std::panic::resume_unwind(e),
            })
            .collect()
    });
    // Back to the items' order: item i is the (i / T)-th result of thread i % T.
    let mut iters: Vec<_> = parts.into_iter().map(Vec::into_iter).collect();
    (0..items.len()).filter_map(|i| iters[i % n_threads].next()).collect()
}

/// The default number of threads for the diagnosis's parallel parts
/// ([`super::DiagnoseOptions::threads`]): the machine's parallelism, at most 8.
pub fn default_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get()).min(8)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 5 h run at about 20 Hz with a jittered time base and a gap, the table swinging over
    /// 120° arcs at 10 °/min with a rate ripple, cut into 10 s bins.
    fn synthetic() -> (Native, Vec<Bin>) {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut t, mut dt, mut gap_before) = (Vec::new(), Vec::new(), Vec::new());
        let mut now = 0.0;
        while now < 5.0 * 3600.0 {
            let step = 0.05 * (1.0 + 0.2 * (uniform() - 0.5));
            // A 3 s gap at 1 h: the interval after it counts as a nominal one.
            let gap = t.len() == 72_000;
            now += if gap { 3.0 } else { step };
            t.push(now);
            dt.push(if gap { 0.05 } else { step });
            gap_before.push(gap);
        }
        let rate = 10f64.to_radians() / 60.0;
        let arc = 120f64.to_radians();
        let (mut angle, mut table_rate) = (Vec::new(), Vec::new());
        for (&tk, &d) in t.iter().zip(&dt) {
            let mid = tk - 0.5 * d;
            let phase = (mid * rate / arc).rem_euclid(2.0);
            let (a, r) = if phase < 1.0 { (phase, rate) } else { (2.0 - phase, -rate) };
            angle.push(0.3 + arc * a);
            table_rate.push(r * (1.0 + 3e-5 * (12.0 * arc * a).sin()));
        }
        let n = t.len();
        let mut bins = Vec::new();
        let mut first = 0;
        while first < n {
            let start = t[first] - dt[first];
            let mut end = first + 1;
            while end < n && !gap_before[end] && t[end - 1] - start < 10.0 - 1e-9 {
                end += 1;
            }
            bins.push(Bin {
                first,
                end,
                start_s: start,
                end_s: t[end - 1],
                table_rate_rad_s: table_rate[first],
                table_accel_rad_s2: 0.0,
                transition: false,
            });
            first = end;
        }
        let zeros = vec![0.0; n];
        let native = Native {
            t,
            dt,
            gap_before,
            v: zeros.clone(),
            temp_c: zeros.clone(),
            temp_rate_c_s: zeros.clone(),
            air_c: zeros,
            angle_mid_rad: angle,
            table_rate_rad_s: table_rate,
        };
        (native, bins)
    }

    /// The periodic bias's grid over `bins`.
    fn periodic_grid(bins: &[Bin]) -> Vec<f64> {
        match bench_physics::effects::EffectId::PeriodicBias.effect().grid() {
            bench_physics::effects::Grid::Periods { min_s, min_cycles, most } => {
                super::super::period_grid(bins, min_s, min_cycles, most)
            }
            _ => Vec::new(),
        }
    }

    fn orders() -> Vec<f64> {
        (1..=64).map(f64::from).collect()
    }

    fn max_abs_diff(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .flat_map(|(x, y)| {
                assert_eq!(x.len(), y.len());
                x.iter().zip(y).map(|(u, v)| (u - v).abs())
            })
            .fold(0.0, f64::max)
    }

    /// The rotated grids (several anchors each) agree with the direct `sin`/`cos` to 1e-13 on
    /// unit columns (the ripple's relative to its amplitude). Without the per-bin correction of
    /// the frequencies' uneven spacing the periodic columns are off by ~2e-13 here.
    #[test]
    fn rotated_grid_agrees_with_sin_cos() {
        let (nat, bins) = synthetic();
        let axis = -1.0;
        let periods = periodic_grid(&bins);
        assert!(periods.len() > 3 * ANCHOR_EVERY, "{} periods", periods.len());
        let memo = ColumnMemo::default();
        memo.prefill_on(&nat, &bins, axis, &orders(), &periods, 2);
        let amp = nat.table_rate_rad_s.iter().fold(0.0f64, |m, r| m.max(r.abs()));
        let (mut worst_angle, mut worst_ripple, mut worst_periodic) = (0.0f64, 0.0f64, 0.0f64);
        let map = memo.lock();
        for k in orders() {
            let (angle, ripple) = angle_and_ripple(&nat, &bins, axis, k);
            worst_angle = worst_angle.max(max_abs_diff(&map[&(Kind::Angle, k.to_bits())], &angle));
            let r = max_abs_diff(&map[&(Kind::Ripple, k.to_bits())], &ripple);
            worst_ripple = worst_ripple.max(r / amp);
        }
        for &p in &periods {
            let direct = periodic(&nat, &bins, p);
            let d = max_abs_diff(&map[&(Kind::Periodic, p.to_bits())], &direct);
            worst_periodic = worst_periodic.max(d);
        }
        eprintln!("max |rotated − direct|: angle {worst_angle:e}, ripple {worst_ripple:e} (of its amplitude), periodic {worst_periodic:e}");
        assert!(worst_angle <= 1e-13, "angle {worst_angle:e}");
        assert!(worst_ripple <= 1e-13, "ripple {worst_ripple:e}");
        assert!(worst_periodic <= 1e-13, "periodic {worst_periodic:e}");
        // Rotated, not computed directly: not every column is bit for bit the direct one.
        assert!(worst_periodic > 0.0 && worst_angle > 0.0);
    }

    /// The columns are the same bits whichever number of threads computes them.
    #[test]
    fn the_threads_do_not_change_the_columns() {
        let (nat, bins) = synthetic();
        let periods = periodic_grid(&bins);
        let columns_on = |threads: usize| {
            let memo = ColumnMemo::default();
            memo.prefill_on(&nat, &bins, 1.0, &orders(), &periods, threads);
            let mut all: Vec<(Key, Vec<Vec<u64>>)> = memo
                .lock()
                .iter()
                .map(|(k, cols)| {
                    (*k, cols.iter().map(|c| c.iter().map(|v| v.to_bits()).collect()).collect())
                })
                .collect();
            all.sort_by_key(|(k, _)| (k.0 as u8, k.1));
            all
        };
        let one = columns_on(1);
        assert_eq!(one.len(), 2 * 64 + periods.len());
        for threads in [2, 3, 8] {
            assert!(one == columns_on(threads), "{threads} threads");
        }
    }

    /// A period off the evenly spaced grid is computed directly, bit for bit as `bin_mean`, and
    /// so is a non-integer angle order; the others are rotated.
    #[test]
    fn values_off_the_grid_are_computed_directly() {
        let (nat, bins) = synthetic();
        let mut periods = periodic_grid(&bins)[..8].to_vec();
        periods[3] *= 1.0 + 1e-9;
        let memo = ColumnMemo::default();
        memo.prefill_on(&nat, &bins, 1.0, &[2.5], &periods, 2);
        let map = memo.lock();
        for (j, &p) in periods.iter().enumerate() {
            let direct = periodic(&nat, &bins, p);
            let got = &map[&(Kind::Periodic, p.to_bits())];
            if j == 3 {
                assert_eq!(got, &direct);
            } else {
                assert!(max_abs_diff(got, &direct) <= 1e-13, "period {j}");
            }
        }
        let (angle, ripple) = angle_and_ripple(&nat, &bins, 1.0, 2.5);
        assert_eq!(map[&(Kind::Angle, 2.5f64.to_bits())], angle);
        assert_eq!(map[&(Kind::Ripple, 2.5f64.to_bits())], ripple);
    }
}
