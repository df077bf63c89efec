//! Whether the calibration's fit fits, said plainly: the checks of
//! [`bench_analysis::fit_check`] on the rate-domain and angle-domain fits, the bootstrap σ
//! against the noise-model bound, the two domains against each other, and where the residual
//! strays, with what the table and the chamber were doing there.
//!
//! A fit that fails any check is **poor**: its coefficients are printed marked as such, no
//! `calibration.toml` is written unless asked, and `bench calibrate` exits with "fit poor".

use bench_analysis::fit_check::{block_excursions, rms_in_band, BlockTest, RMS_BAND};
use bench_physics::ModelKey;
use serde::Serialize;

use super::CalibrationOutcome;
use crate::display::hms;

/// Family-wise false-alarm level of the block test on a sound fit.
pub const BLOCK_ALPHA: f64 = 0.01;

/// Bootstrap σ over the noise-model bound outside this band means the residual does not have
/// the noise model's correlation: the moving-block bootstrap (blocks several correlation
/// lengths long) and the bound agree within a factor 2 when it does.
pub const BOOTSTRAP_BAND: (f64, f64) = (0.5, 2.0);

/// Rate-domain and angle-domain estimates share their data, so they differ by much less than
/// either σ on a sound fit; a difference above this many σ (the larger of the two) means the
/// two domains weigh something unmodelled differently (a transient, ripple, a time error).
pub const DOMAIN_SIGMAS: f64 = 3.0;

/// One check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    /// Short name: `rate_whitened_rms`, `angle_whitened_rms`, `residual_blocks`,
    /// `bootstrap_vs_bound`, `rate_vs_angle`.
    pub key: &'static str,
    /// Passed.
    pub passed: bool,
    /// The statistic.
    pub value: f64,
    /// Its allowed range, as text.
    pub allowed: String,
    /// One sentence on what was measured.
    pub text: String,
}

/// A stretch where the residual is far outside the noise model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Excursion {
    /// The window's label.
    pub window: String,
    /// From, s since the recording's time zero.
    pub start_s: f64,
    /// Until, s.
    pub end_s: f64,
    /// Block mean in noise units (N(0, 1) on a sound fit).
    pub z: f64,
    /// What the table and chamber were doing, in words.
    pub context: String,
}

/// The verdict on a calibration's fit.
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct FitQuality {
    /// `sound` (every check passed, every coefficient determined), `incomplete` (every check
    /// passed, some coefficient held: not determined by the run) or `poor` (a check failed).
    pub verdict: &'static str,
    /// Every check made.
    pub checks: Vec<Check>,
    /// The largest excursions of the rate-domain residual (at most 5), largest first.
    pub excursions: Vec<Excursion>,
    /// Blocks tested and the |z| threshold, for the record.
    pub blocks: usize,
    /// |z| threshold of the block test.
    pub block_threshold: f64,
}

impl FitQuality {
    /// Whether any check failed.
    pub fn poor(&self) -> bool {
        self.checks.iter().any(|c| !c.passed)
    }

    /// The failed checks' sentences and the excursions, as lines for a terminal.
    pub fn lines(&self) -> Vec<String> {
        let mut out: Vec<String> =
            self.checks.iter().filter(|c| !c.passed).map(|c| c.text.clone()).collect();
        for x in &self.excursions {
            out.push(format!(
                "residual {:+.1}σ over {}–{} in `{}`: {}",
                x.z,
                hms(x.start_s),
                hms(x.end_s),
                x.window,
                x.context
            ));
        }
        out
    }
}

/// Judge `outcome`'s fits.
pub fn judge(outcome: &CalibrationOutcome) -> FitQuality {
    let cal = &outcome.calibration;
    let mut checks = Vec::new();
    let mut test: Option<BlockTest> = None;
    let band = format!("{}–{}", RMS_BAND.0, RMS_BAND.1);
    let joint = cal.joint.as_ref().ok();
    let angle = cal.angle.as_ref().and_then(|a| a.as_ref().ok());

    let rms_check = |key: &'static str, domain: &str, v: f64| Check {
        key,
        passed: rms_in_band(v),
        value: v,
        allowed: band.clone(),
        text: format!(
            "{domain}-domain whitened residual RMS {v:.3} (the noise model predicts 1; allowed \
             {band})"
        ),
    };
    if let Some(j) = joint.filter(|j| j.whitened_residual_rms.is_finite()) {
        checks.push(rms_check("rate_whitened_rms", "rate", j.whitened_residual_rms));
    }
    if let Some(a) = angle {
        checks.push(rms_check("angle_whitened_rms", "angle", a.whitened_residual_rms));
    }
    if let Some(j) = joint {
        let lens: Vec<usize> = cal.model_windows.iter().map(|w| w.len()).collect();
        let time: Vec<f64> =
            cal.model_windows.iter().flat_map(|w| w.time_s().iter().copied()).collect();
        if j.residual_z.len() == time.len() && !time.is_empty() {
            let t = block_excursions(&j.residual_z, &time, &lens, BLOCK_ALPHA);
            checks.push(Check {
                key: "residual_blocks",
                passed: t.excursions.is_empty(),
                value: t.max_abs_z,
                allowed: format!("|z| ≤ {:.2}", t.threshold),
                text: format!(
                    "{} of {} residual blocks (10 s, 1 min, 5 min) lie beyond {:.2}σ, the level \
                     a sound fit exceeds with probability {BLOCK_ALPHA}; the largest is {:.1}σ",
                    t.excursions.len(),
                    t.blocks,
                    t.threshold,
                    t.max_abs_z
                ),
            });
            test = Some(t);
        }
        if j.estimator == bench_analysis::joint_fit::Estimator::Gls {
            let worst = ModelKey::CALIBRATED
                .into_iter()
                .filter_map(|k| j.estimate(k).filter(|e| !e.held).map(|e| (k, e)))
                .map(|(k, e)| (k, e.bootstrap_std_err / e.noise_model_std_err))
                .filter(|(_, r)| r.is_finite())
                .max_by(|a, b| spread(a.1).total_cmp(&spread(b.1)));
            if let Some((k, r)) = worst {
                checks.push(Check {
                    key: "bootstrap_vs_bound",
                    passed: (BOOTSTRAP_BAND.0..=BOOTSTRAP_BAND.1).contains(&r),
                    value: r,
                    allowed: format!("{}–{}", BOOTSTRAP_BAND.0, BOOTSTRAP_BAND.1),
                    text: format!(
                        "bootstrap σ over the noise-model bound: {r:.2} at worst ({}; allowed \
                         {}–{})",
                        k.key(),
                        BOOTSTRAP_BAND.0,
                        BOOTSTRAP_BAND.1
                    ),
                });
            }
        }
    }
    if let (Some(j), Some(a)) = (joint, angle) {
        let worst = ModelKey::CALIBRATED
            .into_iter()
            .zip(a.estimates())
            .filter_map(|(k, ae)| {
                let je = j.estimate(k).filter(|e| !e.held)?;
                let s = je.std_err.max(ae.std_err);
                Some((k, (je.value - ae.value).abs() / s))
            })
            .filter(|(_, d)| d.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((k, d)) = worst {
            checks.push(Check {
                key: "rate_vs_angle",
                passed: d <= DOMAIN_SIGMAS,
                value: d,
                allowed: format!("≤ {DOMAIN_SIGMAS}σ"),
                text: format!(
                    "rate and angle domains differ by {d:.1}σ at worst ({}; allowed \
                     {DOMAIN_SIGMAS}σ)",
                    k.key()
                ),
            });
        }
    }

    let excursions = test
        .as_ref()
        .map(|t| {
            t.excursions
                .iter()
                .take(5)
                .map(|x| Excursion {
                    window: cal
                        .windows
                        .get(x.window)
                        .map_or_else(|| format!("window {}", x.window), |w| w.label.clone()),
                    start_s: x.start_s,
                    end_s: x.end_s,
                    z: x.z,
                    context: context(outcome, x.window, x.start_s, x.end_s),
                })
                .collect()
        })
        .unwrap_or_default();
    let mut q = FitQuality {
        verdict: "sound",
        checks,
        excursions,
        blocks: test.as_ref().map_or(0, |t| t.blocks),
        block_threshold: test.as_ref().map_or(f64::NAN, |t| t.threshold),
    };
    if q.poor() {
        q.verdict = "poor";
    } else if cal.incomplete() {
        q.verdict = "incomplete";
    }
    q
}

/// Distance of a ratio from 1 on a log scale.
fn spread(r: f64) -> f64 {
    r.ln().abs()
}

/// What the table and chamber were doing over `[start_s, end_s]` of window `w`.
fn context(outcome: &CalibrationOutcome, w: usize, start_s: f64, end_s: f64) -> String {
    let data = &outcome.data;
    let mut parts = Vec::new();
    if let Some(win) = outcome.calibration.model_windows.get(w) {
        let (ws, we) = (win.time_s()[0], win.time_s()[win.len() - 1]);
        if start_s - ws < 30.0 {
            parts.push(format!("the window's first {:.0} s", end_s - ws));
        } else if we - end_s < 30.0 {
            parts.push(format!("the window's last {:.0} s", we - start_s));
        }
    }
    let mid = 0.5 * (start_s + end_s);
    match data.motion.segment_at(mid) {
        Some(s) => parts.push(format!(
            "table steady at {:+.2} °/min",
            crate::display::TABLE_RATE.of(s.rate_rad_s)
        )),
        None => parts.push("table not steady".into()),
    }
    if let Some(x) = data
        .exclusions
        .iter()
        .filter(|x| x.start_s <= end_s + 10.0 && start_s - 10.0 <= x.end_s)
        .min_by(|a, b| (a.start_s - mid).abs().total_cmp(&(b.start_s - mid).abs()))
    {
        parts.push(format!(
            "next to a {} left out ({}–{})",
            x.why.key().replace('_', " "),
            hms(x.start_s),
            hms(x.end_s)
        ));
    }
    let series = &data.temperature;
    if series.time_s.len() >= 2 {
        let at = |t: f64| series.sample(&[t])[0];
        let (t0, t1) = (at(start_s), at(end_s));
        let span = (end_s - start_s).max(1.0);
        parts.push(format!(
            "model temperature {:.1} °C changing {:+.2} °C/min",
            0.5 * (t0 + t1),
            (t1 - t0) / span * 60.0
        ));
    }
    parts.join(", ")
}
