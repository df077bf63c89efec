//! The located mismatch: each step of the run as a window of time, with the refit residual's
//! mean there against the noise model ([`bench_analysis::diagnose::Location::steps`]), the
//! temperature it spanned and how much of it the effects found account for. Printed by
//! `bench diagnose` and drawn in the report's location figure; one computation for both.

use bench_analysis::diagnose::{Diagnosis, Region};
use bench_physics::allan::normal_quantile;

use super::DiagnoseOutcome;

/// One step of the run as a located window.
#[derive(Debug, Clone, PartialEq)]
pub struct LocatedWindow {
    /// Step index in the scenario.
    pub index: u64,
    /// The step's label (its name when it has none), with its index: `#3 record cw 20C`.
    pub name: String,
    /// Whether it is a record step.
    pub record: bool,
    /// Start, s from the recording's time zero.
    pub start_s: f64,
    /// End, s from the time zero.
    pub end_s: f64,
    /// Model temperature (bin means) at the window's first and last bin, and its lowest and
    /// highest, °C.
    pub temp_c: TempSpan,
    /// Bins in it.
    pub bins: usize,
    /// Mean residual after the parameter refit, rad/s: what the window holds that the refitted
    /// model does not.
    pub mean: f64,
    /// Its 1σ under the noise model, rad/s.
    pub sigma: f64,
    /// The effects found, summed, over the window's bins (mean, rad/s), and the one with the
    /// largest mean there; `None` when no effect was found.
    pub explained: Option<(f64, &'static str)>,
}

impl LocatedWindow {
    /// mean / σ.
    pub fn z(&self) -> f64 {
        self.mean / self.sigma
    }
}

/// The temperature a window spans, °C.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TempSpan {
    /// At the first bin.
    pub first: f64,
    /// At the last bin.
    pub last: f64,
    /// Lowest.
    pub min: f64,
    /// Highest.
    pub max: f64,
}

impl TempSpan {
    /// `20.0 °C` when it moved less than 1 °C, else `20.0 → 40.0 °C` (first to last bin).
    pub fn text(&self) -> String {
        if !(self.first.is_finite() && self.last.is_finite()) {
            return "—".into();
        }
        if self.max - self.min < 1.0 {
            format!("{:.1} °C", 0.5 * (self.min + self.max))
        } else {
            format!("{:.1} → {:.1} °C", self.first, self.last)
        }
    }
}

/// The located windows of a diagnosis, in time order, with the level beyond which a window's
/// mean departs from the noise model.
#[derive(Debug, Clone, PartialEq)]
pub struct Located {
    /// One per step with bins in it, in time order.
    pub windows: Vec<LocatedWindow>,
    /// |z| beyond which a window departs from the noise model: two-sided, the diagnosis's α
    /// shared over the windows (Bonferroni), so a null recording shows none with probability
    /// 1 − α.
    pub z_threshold: f64,
    /// The family-wise α the threshold holds.
    pub alpha: f64,
    /// Times the table turned the other way (its rate changed sign, rests between included),
    /// s from the time zero.
    pub reversals_s: Vec<f64>,
}

impl Located {
    /// Whether `w` departs from the noise model.
    pub fn departs(&self, w: &LocatedWindow) -> bool {
        w.z().abs() > self.z_threshold
    }

    /// The windows by |z|, largest first.
    pub fn by_z(&self) -> Vec<&LocatedWindow> {
        let mut v: Vec<&LocatedWindow> = self.windows.iter().collect();
        v.sort_by(|a, b| b.z().abs().total_cmp(&a.z().abs()));
        v
    }
}

/// The step index a location region names (`#12 record cw …` → 12).
fn region_index(r: &Region) -> Option<u64> {
    r.name.strip_prefix('#')?.split(' ').next()?.parse().ok()
}

/// Table rates under this are rest (as the diagnosis's location classes have it).
const REST_RAD_S: f64 = 1e-6;

/// The times the table's bin-mean rate changes sign, between the two bins where it does.
fn reversals(d: &Diagnosis) -> Vec<f64> {
    let s = &d.series;
    let mut out = Vec::new();
    let mut last: Option<(f64, f64)> = None; // (sign, time of the last bin with that sign)
    for (t, r) in s.time_s.iter().zip(&s.table_rate_rad_s) {
        if !(r.is_finite() && r.abs() > REST_RAD_S) {
            continue;
        }
        let sign = r.signum();
        if let Some((was, at)) = last {
            if was != sign {
                out.push(0.5 * (at + t));
            }
        }
        last = Some((sign, *t));
    }
    out
}

/// The located windows of `o`'s diagnosis.
pub fn located(o: &DiagnoseOutcome) -> Located {
    let d = &o.diagnosis;
    let s = &d.series;
    let steps = &o.data.series.steps;
    let mut windows = Vec::new();
    for r in &d.location.steps {
        let Some(step) = region_index(r).and_then(|i| steps.iter().find(|s| s.index == i)) else {
            continue;
        };
        let idx: Vec<usize> = (0..s.time_s.len())
            .filter(|&i| s.time_s[i] >= step.start_s && s.time_s[i] < step.end_s)
            .collect();
        let temps: Vec<f64> = idx.iter().map(|&i| s.temp_c[i]).filter(|t| t.is_finite()).collect();
        let temp_c = TempSpan {
            first: temps.first().copied().unwrap_or(f64::NAN),
            last: temps.last().copied().unwrap_or(f64::NAN),
            min: temps.iter().copied().fold(f64::INFINITY, f64::min),
            max: temps.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        };
        let mean_over = |c: &[f64]| {
            if idx.is_empty() {
                0.0
            } else {
                idx.iter().map(|&i| c[i]).sum::<f64>() / idx.len() as f64
            }
        };
        let explained = (!s.contributions.is_empty()).then(|| {
            let each: Vec<(f64, &'static str)> =
                s.contributions.iter().map(|(id, c)| (mean_over(c), id.key())).collect();
            let total = each.iter().map(|e| e.0).sum();
            let largest =
                each.iter().max_by(|a, b| a.0.abs().total_cmp(&b.0.abs())).map_or("", |e| e.1);
            (total, largest)
        });
        windows.push(LocatedWindow {
            index: step.index,
            name: r.name.clone(),
            record: bench_recording::message::is_record_label(&step.label),
            start_s: step.start_s,
            end_s: step.end_s,
            temp_c,
            bins: r.bins,
            mean: r.mean,
            sigma: r.sigma,
            explained,
        });
    }
    windows.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
    let alpha = o.options.alpha;
    let n = windows.len().max(1) as f64;
    Located {
        windows,
        z_threshold: normal_quantile(1.0 - alpha / (2.0 * n)),
        alpha,
        reversals_s: reversals(d),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_shows_its_direction_and_a_soak_one_temperature() {
        let soak = TempSpan { first: 20.1, last: 19.9, min: 19.8, max: 20.3 };
        assert_eq!(soak.text(), "20.1 °C");
        let ramp = TempSpan { first: 40.0, last: 0.2, min: 0.2, max: 40.0 };
        assert_eq!(ramp.text(), "40.0 → 0.2 °C");
        let none = TempSpan { first: f64::NAN, last: f64::NAN, min: f64::NAN, max: f64::NAN };
        assert_eq!(none.text(), "—");
    }

    #[test]
    fn regions_name_their_step() {
        let r = |name: &str| Region { name: name.into(), bins: 1, mean: 0.0, sigma: 1.0 };
        assert_eq!(region_index(&r("#12 record cw ramp 20C to 40C")), Some(12));
        assert_eq!(region_index(&r("#0 soak")), Some(0));
        assert_eq!(region_index(&r("cw")), None);
    }
}
