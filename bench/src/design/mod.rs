//! Procedure design: the shortest chamber run that reaches the σ a lab asks for, or the
//! smallest σ in a time budget (`bench design`, docs/design.md).
//!
//! **The prediction.** A procedure's σ per coefficient is its Cramér–Rao bound under the
//! gyro's noise model (white noise `arw`, the flicker floor `bias_instability` as Gauss–Markov
//! states; [`bench_analysis::information`]), from the design matrix the calibration fits: the
//! record windows' `1`, `Ω_in + Ω_E`, `T − T0`, `dT/dt` (the model temperature: the gyro's
//! sensor, or for a gyro without one the chamber air through the fitted lag, whose
//! sensitivity is then a fifth, nuisance column). [`predict_procedure`] lays the windows out
//! from the procedure's nominal timeline ([`procedure`]); [`predict_plan`] takes them from a
//! simulated run of any scenario, through the calibration's own loader.
//!
//! **The search** ([`search`]): a grid over the discrete choices (sweep rate, table rate,
//! reversal period, holds), and for each the number of sweeps by bisection (σ falls as sweeps
//! are added): the fewest that reach every target, or the most that fit the budget. The
//! candidate kept is the shortest (targets) or the one with the smallest largest ratio of σ
//! to its reference (budget). The range is the widest the bench and the gyro allow (a wider
//! range only adds temperature lever arm); no soak steps (the model temperature is measured,
//! or fitted through the lag), so a gyro without a sensor is never soaked on it.

pub mod procedure;

use bench_analysis::information::{identify, Determination, InformationOptions};
use bench_analysis::joint_fit::{NoiseSpec, Nuisance};
use bench_analysis::RecordWindow;
use bench_physics::units::DEG_PER_MIN;
use bench_physics::{GyroModel, ModelKey};

pub use procedure::{Procedure, ScenarioSetup, Timeline};

use crate::plan::RunPlan;
use crate::runner::simulate_in_memory;
use crate::scenario::Capabilities;

/// The bench's and the gyro's limits a design keeps within.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Widest sweep range: the chamber's and the gyro's operating range, °C.
    pub range_c: (f64, f64),
    /// Fastest ramp both ways (the lesser of heating and cooling), °C/min.
    pub max_ramp_c_min: f64,
    /// Fastest table rate (table and gyro input range), °/min.
    pub max_table_deg_min: f64,
    /// Table acceleration used (the lesser of 1 °/s² and the table's maximum), °/s².
    pub accel_deg_s2: f64,
    /// The gyro has its own temperature sensor.
    pub gyro_sensor: bool,
}

impl Limits {
    /// From a bench's capabilities.
    pub fn of(caps: &Capabilities) -> Self {
        let c = &caps.chamber.capabilities;
        let g = &caps.gyro.capabilities;
        let t = &caps.table.capabilities;
        let deg = std::f64::consts::PI / 180.0;
        Self {
            range_c: (
                c.min_temp_c.max(g.operating_temp_c.0),
                c.max_temp_c.min(g.operating_temp_c.1),
            ),
            max_ramp_c_min: 60.0 * c.max_heat_rate_c_s.min(c.max_cool_rate_c_s),
            max_table_deg_min: t.max_rate_rad_s.min(g.max_rate_rad_s) / DEG_PER_MIN,
            accel_deg_s2: (t.max_accel_rad_s2 / deg).min(1.0),
            gyro_sensor: g.has_temperature,
        }
    }
}

/// A procedure's predicted σ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prediction {
    /// Cramér–Rao σ per coefficient (`ModelKey::CALIBRATED` order, SI); infinite when the
    /// procedure does not determine it.
    pub sigma: [f64; 4],
    /// Chamber time, s.
    pub duration_s: f64,
}

impl Prediction {
    /// The largest ratio of σ to `reference` over the coefficients that have one.
    pub fn worst_ratio(&self, reference: &[Option<f64>; 4]) -> f64 {
        self.sigma.iter().zip(reference).filter_map(|(s, r)| r.map(|r| s / r)).fold(0.0, f64::max)
    }
}

/// The noise model the prediction uses: the model's `arw` and flicker floor.
pub fn noise_of(model: &GyroModel) -> NoiseSpec {
    NoiseSpec { arw: model.arw, flicker_floor: model.bias_instability, rrw: 0.0 }
}

/// The bound σ of the coefficients from record windows (and a fitted lag's nuisance column).
pub fn predict_windows(
    windows: &[RecordWindow],
    nuisance: Option<&Nuisance>,
    model: &GyroModel,
    latitude_deg: f64,
    axis_up: bool,
) -> anyhow::Result<[f64; 4]> {
    let opts = InformationOptions {
        reference_temperature_c: model.reference_temperature,
        earth_rad_s: bench_physics::earth::vertical_rate_rad_s(latitude_deg, axis_up),
        rate_window_s: procedure::RATE_WINDOW_S,
        noise: Some(noise_of(model)),
        expected: [None; 4],
    };
    let d = identify(windows, nuisance, &opts)?;
    Ok(d.map(|d: Determination| if d.determined() { d.sigma_bound } else { f64::INFINITY }))
}

/// A procedure's predicted σ from its nominal timeline, sampled every `dt_s`.
pub fn predict_procedure(
    p: &Procedure,
    model: &GyroModel,
    latitude_deg: f64,
    lag_fitted: bool,
    dt_s: f64,
) -> Option<Prediction> {
    let tl = p.timeline()?;
    let (w, nu) = tl.windows(dt_s, model, lag_fitted)?;
    let sigma = predict_windows(&w, nu.as_ref(), model, latitude_deg, true).ok()?;
    Some(Prediction { sigma, duration_s: tl.duration_s })
}

/// Any scenario's predicted σ for the gyro `model`: the scenario simulated with `model` as its
/// truth and nominal model, its record windows taken as `bench calibrate` takes them, and the
/// bound computed on them; with `lag_fitted` the model temperature is the chamber air through
/// the model's lag, fitted. Chamber time: the simulated run's.
pub fn predict_plan(
    plan: &RunPlan,
    model: &GyroModel,
    lag_fitted: bool,
) -> anyhow::Result<Prediction> {
    let mut plan = plan.clone();
    plan.gyro.model = model.clone();
    plan.sim.truth = model.clone();
    let (report, bytes) = simulate_in_memory(&plan, 1)?;
    anyhow::ensure!(report.completed(), "the simulated run did not complete: {}", report.outcome);
    let rec = bench_recording::Recording::from_bytes(&bytes)?;
    let data = bench_report::calibrate::calibration_data(bench_report::load::load(&rec)?)?;
    let rw = procedure::RATE_WINDOW_S;
    let tau = model.thermal_time_constant;
    let (series, nuisance_needed) = if lag_fitted && tau > 0.0 {
        (data.chamber.lagged(tau), true)
    } else {
        (data.temperature.clone(), false)
    };
    let windows: Vec<RecordWindow> = if lag_fitted {
        // The calibration of a gyro without a sensor sees the air only.
        data.windows
            .iter()
            .map(|w| {
                RecordWindow::new(
                    w.label(),
                    w.time_s().to_vec(),
                    w.gyro_rate_rad_s().to_vec(),
                    w.table_rate_rad_s().to_vec(),
                    None,
                    w.chamber_temp_c().to_vec(),
                )
            })
            .collect::<Result<_, _>>()?
    } else {
        data.windows.clone()
    };
    let mw = bench_analysis::calibrate::model_series_windows(&windows, &series, rw);
    let nuisance = if nuisance_needed {
        let c = [model.bias, model.scale_factor_error, model.temp_coeff, model.temp_rate_coeff];
        bench_analysis::calibrate::lag_nuisance(&mw, &data.chamber, tau, c, rw)
    } else {
        None
    };
    let sigma = predict_windows(
        &mw,
        nuisance.as_ref(),
        model,
        plan.site.latitude_deg,
        plan.site.axis_up(),
    )?;
    Ok(Prediction { sigma, duration_s: report.bench_time.as_secs_f64() })
}

/// What the search aims for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// Every coefficient with a target at or below it, in the least chamber time.
    Targets([Option<f64>; 4]),
    /// The smallest largest ratio of σ to the reference, within the hours.
    Budget {
        /// Chamber time allowed, h.
        hours: f64,
        /// The σ the ratio is taken to, per coefficient.
        reference: [Option<f64>; 4],
    },
}

/// The grid the search walks (each value within the bench's limits).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Sweep rates, °C/min.
    pub ramps_c_min: Vec<f64>,
    /// Table rates, °/min.
    pub table_deg_min: Vec<f64>,
    /// Reversal periods, min.
    pub reversal_min: Vec<f64>,
    /// Holds at the ends, min.
    pub hold_min: Vec<f64>,
    /// Most sweeps tried.
    pub max_legs: usize,
    /// Sample interval of the predicted windows, s (white noise's information does not depend
    /// on it while the regressors are smooth over it: each sample's variance is `N²/dt`).
    pub dt_s: f64,
}

impl Default for Grid {
    fn default() -> Self {
        Self {
            ramps_c_min: vec![0.5, 1.0, 2.0, 3.0, 5.0],
            table_deg_min: vec![10.0, 30.0, 60.0],
            reversal_min: vec![5.0, 10.0, 20.0, 40.0],
            hold_min: vec![0.0, 20.0],
            max_legs: 24,
            dt_s: 5.0,
        }
    }
}

/// The gyro and site a design is for.
#[derive(Debug, Clone, PartialEq)]
pub struct Subject {
    /// The gyro's model (its noise and lag).
    pub model: GyroModel,
    /// Site latitude, degrees.
    pub latitude_deg: f64,
    /// Start temperature, °C.
    pub initial_c: f64,
}

/// The design found.
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// The procedure.
    pub procedure: Procedure,
    /// Its prediction (nominal timeline).
    pub prediction: Prediction,
    /// Candidates evaluated.
    pub evaluated: usize,
}

/// The grid search (module docs); `None` when no candidate within the limits reaches the
/// targets (or fits the budget).
pub fn search(subject: &Subject, limits: &Limits, grid: &Grid, goal: Goal) -> Option<Design> {
    let lag_fitted = !limits.gyro_sensor;
    let mut evaluated = 0;
    let mut best: Option<(f64, Procedure, Prediction)> = None;
    let ramps = grid.ramps_c_min.iter().filter(|&&r| r <= limits.max_ramp_c_min + 1e-9);
    for &ramp in ramps {
        for &w in grid.table_deg_min.iter().filter(|&&w| w <= limits.max_table_deg_min + 1e-9) {
            for &rev in &grid.reversal_min {
                for &hold in &grid.hold_min {
                    let base = Procedure {
                        range_c: limits.range_c,
                        ramp_c_min: ramp,
                        legs: 1,
                        table_deg_min: w,
                        reversal_min: rev,
                        hold_min: hold,
                        accel_deg_s2: limits.accel_deg_s2,
                        initial_c: subject.initial_c.clamp(limits.range_c.0, limits.range_c.1),
                        transit_c_min: limits.max_ramp_c_min,
                    };
                    let mut eval = |legs: usize| {
                        evaluated += 1;
                        let p = Procedure { legs, ..base };
                        predict_procedure(
                            &p,
                            &subject.model,
                            subject.latitude_deg,
                            lag_fitted,
                            grid.dt_s,
                        )
                        .map(|pr| (p, pr))
                    };
                    let found = match goal {
                        Goal::Targets(t) => fewest_legs(grid.max_legs, |l| {
                            eval(l).filter(|(_, pr)| pr.worst_ratio(&t) <= 1.0)
                        })
                        .map(|(p, pr)| (pr.duration_s, p, pr)),
                        Goal::Budget { hours, reference } => most_legs(grid.max_legs, |l| {
                            eval(l).filter(|(_, pr)| pr.duration_s <= hours * 3600.0)
                        })
                        .map(|(p, pr)| (pr.worst_ratio(&reference), p, pr)),
                    };
                    if let Some(f) = found {
                        if best.as_ref().is_none_or(|b| f.0 < b.0) {
                            best = Some(f);
                        }
                    }
                }
            }
        }
    }
    best.map(|(_, procedure, prediction)| Design { procedure, prediction, evaluated })
}

/// The fewest legs in `1..=max` for which `ok` holds (it holds from some number of legs on):
/// doubling from 1, then bisection, so a short design costs short evaluations.
fn fewest_legs<T>(max: usize, mut ok: impl FnMut(usize) -> Option<T>) -> Option<T> {
    let (mut lo, mut hi) = (0, 1);
    let mut hi_val = loop {
        if let Some(v) = ok(hi) {
            break v;
        }
        if hi >= max {
            return None;
        }
        lo = hi;
        hi = (2 * hi).min(max);
    };
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        match ok(mid) {
            Some(v) => {
                hi = mid;
                hi_val = v;
            }
            None => lo = mid,
        }
    }
    Some(hi_val)
}

/// The most legs in `1..=max` for which `ok` holds (it holds up to some number of legs).
fn most_legs<T>(max: usize, mut ok: impl FnMut(usize) -> Option<T>) -> Option<T> {
    let mut lo_val = ok(1)?;
    let (mut lo, mut hi) = (1, max + 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        match ok(mid) {
            Some(v) => {
                lo = mid;
                lo_val = v;
            }
            None => hi = mid,
        }
    }
    Some(lo_val)
}

/// The largest of `options` within `limit` (with a small tolerance), or `floor` when none is.
pub fn fastest_allowed(options: &[f64], limit: f64, floor: f64) -> f64 {
    options.iter().copied().filter(|x| *x <= limit + 1e-9).fold(floor, f64::max)
}

/// Short names of the coefficients on the command line, in `ModelKey::CALIBRATED` order.
pub const SHORT: [&str; 4] = ["bias", "sf", "k_t", "k_dt"];

/// The coefficient a name on the command line means: the short name or the contract key.
pub fn coefficient(name: &str) -> Option<usize> {
    let name = name.trim();
    SHORT.iter().position(|s| *s == name).or_else(|| {
        ModelKey::from_key(name).and_then(|k| ModelKey::CALIBRATED.iter().position(|c| *c == k))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn subject() -> Subject {
        Subject { model: GyroModel::default(), latitude_deg: 59.94, initial_c: 20.0 }
    }

    fn limits(sensor: bool) -> Limits {
        Limits { gyro_sensor: sensor, ..Limits::of(&crate::simulate::capabilities()) }
    }

    fn procedure(legs: usize) -> Procedure {
        Procedure {
            range_c: (-40.0, 60.0),
            ramp_c_min: 2.0,
            legs,
            table_deg_min: 10.0,
            reversal_min: 10.0,
            hold_min: 0.0,
            accel_deg_s2: 1.0,
            initial_c: 20.0,
            transit_c_min: 5.0,
        }
    }

    #[test]
    fn the_timeline_reverses_the_table_and_sweeps_up_then_down() {
        let tl = procedure(2).timeline().expect("timeline");
        // 60 °C of transit at 5 °C/min, then two 100 °C sweeps at 2 °C/min.
        assert!((tl.duration_s - (12.0 + 100.0) * 60.0).abs() < 1e-6, "{}", tl.duration_s);
        assert_eq!(tl.segments.len(), 10, "{:?}", tl.segments);
        assert!(tl.segments.windows(2).all(|s| s[0].rate_rad_s == -s[1].rate_rad_s));
        assert_eq!(tl.air.last().map(|k| k.1), Some(-40.0));
    }

    #[test]
    fn more_sweeps_lower_every_sigma_and_a_fitted_lag_costs_k_dt() {
        let m = GyroModel::default();
        let one = predict_procedure(&procedure(2), &m, 59.94, false, 2.0).expect("predicts");
        let two = predict_procedure(&procedure(4), &m, 59.94, false, 2.0).expect("predicts");
        for j in 0..4 {
            assert!(two.sigma[j] < one.sigma[j], "{j}: {:?} {:?}", one.sigma, two.sigma);
        }
        let lag = predict_procedure(&procedure(4), &m, 59.94, true, 2.0).expect("predicts");
        assert!(lag.sigma[3] > two.sigma[3], "{:?} vs {:?}", lag.sigma, two.sigma);
    }

    #[test]
    fn white_noise_information_does_not_depend_on_the_sample_interval() {
        let m = GyroModel::default();
        let a = predict_procedure(&procedure(2), &m, 59.94, false, 1.0).expect("predicts");
        let b = predict_procedure(&procedure(2), &m, 59.94, false, 4.0).expect("predicts");
        for j in 0..4 {
            assert!((a.sigma[j] / b.sigma[j] - 1.0).abs() < 0.05, "{j}: {:?} {:?}", a, b);
        }
    }

    #[test]
    fn the_search_meets_its_targets_in_less_time_when_they_are_looser() {
        let grid = Grid {
            ramps_c_min: vec![1.0, 3.0],
            table_deg_min: vec![10.0, 30.0],
            reversal_min: vec![10.0],
            hold_min: vec![0.0],
            max_legs: 8,
            dt_s: 4.0,
        };
        let base = predict_procedure(&procedure(4), &GyroModel::default(), 59.94, false, 4.0)
            .expect("predicts");
        let tight = Goal::Targets(base.sigma.map(Some));
        let loose = Goal::Targets(base.sigma.map(|s| Some(2.0 * s)));
        let a = search(&subject(), &limits(true), &grid, tight).expect("reaches");
        let b = search(&subject(), &limits(true), &grid, loose).expect("reaches");
        assert!(a.prediction.worst_ratio(&base.sigma.map(Some)) <= 1.0);
        assert!(b.prediction.duration_s < a.prediction.duration_s, "{a:?} {b:?}");
        // Unreachable: nothing.
        let never = Goal::Targets(base.sigma.map(|s| Some(1e-3 * s)));
        assert!(search(&subject(), &limits(true), &grid, never).is_none());
    }
}
