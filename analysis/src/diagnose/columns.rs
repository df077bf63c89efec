//! The sinusoidal regressors of the search, computed once per run and in parallel.
//!
//! The angle harmonics, the table's rate ripple and the periodic bias are bin means of
//! `sin`/`cos` over every gyro sample (a 5 h 20 Hz run: 366 k samples per column, ~900 columns
//! over the grids and the family checks). They depend on the run and the grid value only, so
//! each is computed once ([`ColumnMemo`]) and shared by the search, the refinements, the family
//! check, the location and the rate-dependence test. An angle harmonic and the ripple at the
//! same `k` share each sample's `sin(k·θ)` and `cos(k·θ)` (one pass for both).
//!
//! Every column is computed exactly as [`super::series::bin_mean`] of the same expression
//! (the same operations in the same order), so the values are bit for bit those computed
//! without the memo, whichever thread computed them.

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

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<Key, Columns>> {
        // A panic elsewhere cannot leave a half-written entry: entries are inserted whole.
        self.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
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

/// `f` over `items` on up to [`threads`] threads, results in order (each item computed as it
/// would be alone: the results do not depend on the number of threads). Items are dealt out in
/// turn (thread `t` takes items `t`, `t + T`, …), so neighbouring items of unequal cost — a
/// grid's expensive columns next to a cheap grid — are shared evenly.
pub(super) fn par_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let n_threads = threads().min(items.len());
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

/// Threads for the diagnosis's parallel parts: the machine's parallelism, at most 8;
/// `BENCH_DIAGNOSE_THREADS` sets it (1: serial).
pub fn threads() -> usize {
    std::env::var("BENCH_DIAGNOSE_THREADS")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .filter(|&t| t >= 1)
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()).min(8))
}
