//! The whole calibration of one recording's windows: noise terms, which coefficients the
//! procedure determines, the seed's method, the joint fit with the thermal lag where the data
//! can tell it, and what is missing.
//!
//! Order of work ([`calibrate`]):
//!
//! 1. **Classify** windows: a *plateau* has a chamber-air spread ≤ `plateau_span_c`; a
//!    *ramp* is any other window with the table turning; a window at rest is *static*.
//! 2. **Thermal lag** ([`fit_lag`], gyros without their own sensor): the model temperature is
//!    `lag(T_meas, τ)`, where `T_meas` is the whole-run temperature series (the gyro's sensor,
//!    else chamber air). τ is profiled over 0..3000 s by the residual sum of squares of the
//!    joint model. Significance uses the residual's effective sample count `n_eff = n/(2·k_e)`
//!    (`k_e`: its correlation lag): τ̂ is kept only when `n_eff·ΔRSS/RSS` exceeds the χ²₁
//!    quantile of the confidence level; otherwise τ = 0 (the measured temperature). A kept τ̂
//!    is then **fitted with the coefficients** ([`lag_nuisance`]: its linearised effect
//!    `k_t·∂T/∂τ + k_dt·∂Ṫ/∂τ` is a fifth column of both fits), so every σ carries its
//!    uncertainty; the column is taken again at the τ the fit finds until it stops moving
//!    ([`relinearised`]: a first-order column alone leaves k_t and k_dt part of the way).
//! 3. **Noise** ([`noise`]): the overlapping Allan deviation of the thermal model's residual
//!    (OLS, lag included — a coil still settling after a ramp is the model's, not noise),
//!    pooled over the windows at constant chamber temperature (every window when there are
//!    none), its IEEE 952 terms ([`crate::allan_fit`]) and the [`NoiseSpec`] fitted to the
//!    whole curve, whose covariance the fits carry into their standard errors — flicker
//!    correlated over hours, which no block of a bootstrap sees.
//! 4. **Identifiability** ([`crate::information`]), before any estimate: the Fisher
//!    information of the design under that noise model says which coefficients the run
//!    determines; one it does not is **held** at its expected value ([`Expected`]: a prior the
//!    user gives, else the nominal model's) and named, never estimated.
//! 5. **Seed method**, **joint fit** (rate domain) and **angle-domain fit** (the
//!    navigation-solution method, [`crate::angle_fit`], when the table's readings are given) on
//!    the windows with the chosen model temperature, under the same noise model, the held
//!    coefficients fixed.

mod lag;
pub mod noise;

use bench_physics::allan::AdevPoint;
use bench_physics::GyroModel;

use crate::allan_fit::{allan_fit, AllanFit};
use crate::angle_fit::{angle_fit, AngleFit, AngleFitOptions, AngleWindow, TableReadings};
use crate::error::AnalysisError;
use crate::information::{identify, Determination, InformationOptions};
use crate::joint_fit::{
    joint_fit, ols_fit, Held, JointFit, JointFitOptions, NoiseSpec, Nuisance, OlsFit,
};
use crate::seed_method::{seed_calibration, SeedCalibration, SeedOptions};
use crate::temperature_rate::local_linear_rate;
use crate::windows::{Direction, RecordWindow};

use lag::with_model_series;
pub use lag::{fit_lag, lag_nuisance, LagFit};
pub use noise::{fit_noise_spec, fit_noise_spec_all_points, pooled_adev, pooled_adev_series};

/// Where a coefficient's expected value comes from ([`Expected`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExpectedSource {
    /// A prior the user gave (`--prior KEY=VALUE±SIGMA`).
    Prior,
    /// The recording's nominal model (`bench.gyro_model`).
    Nominal,
    /// Neither: a held coefficient is held at 0.
    None,
}

impl ExpectedSource {
    /// As written in the JSON and the calibration file.
    pub fn key(self) -> &'static str {
        match self {
            ExpectedSource::Prior => "prior",
            ExpectedSource::Nominal => "nominal",
            ExpectedSource::None => "none",
        }
    }
}

/// What a coefficient is expected to be before the data: its size for the identifiability
/// test ([`crate::information`]) and the value it is held at when the run does not determine
/// it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Expected {
    /// Value, the contract's unit.
    pub value: f64,
    /// 1σ, when stated (a prior's).
    pub sigma: Option<f64>,
    /// Where it comes from.
    pub source: ExpectedSource,
    /// Whether it sets a size the run must resolve ([`crate::information`]'s size test): a
    /// prior's does; a nominal bias or scale factor (a data sheet's bound, or 0) does not.
    pub sized: bool,
}

impl Expected {
    /// The size a coefficient is expected to have: `max(|value|, σ)`.
    pub fn size(&self) -> f64 {
        self.value.abs().max(self.sigma.unwrap_or(0.0))
    }
}

/// A temperature time series, s and °C, time strictly increasing.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TemperatureSeries {
    /// Time, s.
    pub time_s: Vec<f64>,
    /// Temperature, °C.
    pub temp_c: Vec<f64>,
}

impl TemperatureSeries {
    /// The series through a first-order lag of `tau_s`, started at its first value.
    pub fn lagged(&self, tau_s: f64) -> TemperatureSeries {
        let temp_c = bench_physics::effects::lag_temperature(&self.time_s, &self.temp_c, tau_s);
        TemperatureSeries { time_s: self.time_s.clone(), temp_c }
    }

    /// The series smoothed and its rate (°C, °C/s), each by a centred local linear
    /// regression over `window_s` ([`crate::temperature_rate`]).
    pub fn smoothed(&self, window_s: f64) -> Result<(Vec<f64>, Vec<f64>), AnalysisError> {
        crate::temperature_rate::local_linear_value_and_rate(&self.time_s, &self.temp_c, window_s)
    }

    /// Linear interpolation at times `at` (held at the ends; [`crate::interp`]).
    pub fn sample(&self, at: &[f64]) -> Vec<f64> {
        crate::interp::interp_at(&self.time_s, &self.temp_c, at)
    }
}

/// Settings of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateOptions {
    /// The joint fit's settings — T0 of the coefficients, the site (latitude, axis), the dT/dt
    /// filter's window, the bootstrap's replicates and seed — which the seed method, the lag
    /// profile and the angle-domain fit share. Its noise model, held coefficients and
    /// nuisance are [`calibrate`]'s to set: those given here are not used.
    pub joint: JointFitOptions,
    /// A window is a plateau when its temperature spread is at most this, °C.
    pub plateau_span_c: f64,
    /// Largest temperature difference of a CW/CCW plateau pair, °C.
    pub pair_tolerance_c: f64,
    /// Confidence level of intervals (Allan terms, lag significance).
    pub confidence: f64,
    /// Whether to profile the thermal lag.
    pub fit_lag: bool,
    /// The flicker floor the lab states for this gyro (its `bench.gyro_model`
    /// `bias_instability`, a datasheet value), rad/s: used in the noise model only where the
    /// constant-temperature windows are too short to resolve the floor ([`AllanResult::noise`]).
    pub stated_flicker_floor_rad_s: Option<f64>,
    /// Each coefficient's expected value (`ModelKey::CALIBRATED` order): the identifiability
    /// test's size and the value held when the run does not determine it.
    pub expected: [Option<Expected>; 4],
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        Self {
            joint: JointFitOptions::default(),
            plateau_span_c: 1.0,
            pair_tolerance_c: 1.0,
            confidence: 0.95,
            fit_lag: true,
            stated_flicker_floor_rad_s: None,
            expected: [None; 4],
        }
    }
}

/// What a window is for the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WindowKind {
    /// Constant temperature, table turning.
    Plateau,
    /// Temperature changing, table turning.
    Ramp,
    /// Table at rest.
    Static,
}

/// One window as the calibration saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct WindowSummary {
    /// Step label.
    pub label: String,
    /// Kind.
    pub kind: WindowKind,
    /// Direction of rotation.
    pub direction: Direction,
    /// Samples.
    pub samples: usize,
    /// Duration, s.
    pub duration_s: f64,
    /// Mean model temperature, °C.
    pub mean_temp_c: f64,
    /// Model-temperature spread, °C.
    pub temp_span_c: f64,
    /// Mean table rate, rad/s.
    pub mean_table_rate_rad_s: f64,
}

/// Pooled Allan deviation and its noise terms.
#[derive(Debug, Clone, PartialEq)]
pub struct AllanResult {
    /// Windows pooled.
    pub windows: Vec<String>,
    /// The pooled curve.
    pub points: Vec<AdevPoint>,
    /// IEEE 952 terms.
    pub fit: AllanFit,
}

/// A coefficient held instead of estimated ([`Calibration::held`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldCoefficient {
    /// The value used: the prior's, else the nominal model's (0 without either).
    pub value: f64,
    /// Its 1σ: the prior's, 0 for a nominal value (taken as exact).
    pub sigma: f64,
    /// Where the value comes from.
    pub source: ExpectedSource,
    /// Why the run does not determine it.
    pub determination: Determination,
}

/// Result of [`calibrate`].
#[derive(Debug, Clone)]
pub struct Calibration {
    /// The options used.
    pub options: CalibrateOptions,
    /// The windows, classified.
    pub windows: Vec<WindowSummary>,
    /// Windows with the model temperature used (lag applied).
    pub model_windows: Vec<RecordWindow>,
    /// Allan deviation and noise terms of the thermal model's residual (constant-temperature
    /// windows, else every window).
    pub allan: Result<AllanResult, AnalysisError>,
    /// The noise model both fits used ([`AllanResult::noise`]), if any.
    pub noise_model: Option<NoiseSpec>,
    /// Thermal lag profile.
    pub lag: Option<Result<LagFit, AnalysisError>>,
    /// Which coefficients the run determines ([`crate::information`]), decided before the fit;
    /// an error when it could not be decided (the fit then holds nothing).
    pub identifiability: Result<[Determination; 4], AnalysisError>,
    /// Coefficients held, not estimated (`ModelKey::CALIBRATED` order).
    pub held: [Option<HeldCoefficient>; 4],
    /// The seed's method.
    pub seed: Result<SeedCalibration, AnalysisError>,
    /// The joint fit (rate domain).
    pub joint: Result<JointFit, AnalysisError>,
    /// The angle-domain fit, when the table's readings were given.
    pub angle: Option<Result<AngleFit, AnalysisError>>,
    /// What the data lack, and what could still be estimated, one sentence each.
    pub missing: Vec<String>,
}

impl Calibration {
    /// The calibrated gyro model: the joint fit over `base` (a held coefficient at its held
    /// value), with the noise terms from the Allan deviation and the thermal lag used, where
    /// they were estimated.
    pub fn model(&self, base: &GyroModel) -> Option<GyroModel> {
        let joint = self.joint.as_ref().ok()?;
        let mut m = joint.to_model(base);
        if let Ok(a) = &self.allan {
            m.arw = a.fit.arw.value;
            m.bias_instability = a.fit.flicker_floor().value;
        }
        if let Some(Ok(l)) = &self.lag {
            m.thermal_time_constant = l.fitted_s();
        }
        m.earth_rate = self.options.joint.latitude_deg.is_some() || base.earth_rate;
        Some(m)
    }

    /// Whether any coefficient is held: the calibration is incomplete.
    pub fn incomplete(&self) -> bool {
        self.held.iter().any(Option::is_some)
    }
}

fn kind(w: &RecordWindow, opts: &CalibrateOptions) -> WindowKind {
    if w.direction() == Direction::Rest {
        WindowKind::Static
    } else if w.chamber_span_c() <= opts.plateau_span_c {
        WindowKind::Plateau
    } else {
        WindowKind::Ramp
    }
}

/// Stage 1: the windows classified, and what the procedure lacks.
fn classify(
    windows: &[RecordWindow],
    opts: &CalibrateOptions,
) -> (Vec<WindowSummary>, Vec<String>) {
    let mut missing = Vec::new();
    let summaries: Vec<WindowSummary> = windows
        .iter()
        .map(|w| WindowSummary {
            label: w.label().to_owned(),
            kind: kind(w, opts),
            direction: w.direction(),
            samples: w.len(),
            duration_s: w.time_s()[w.len() - 1] - w.time_s()[0],
            mean_temp_c: w.mean_temperature_c(),
            temp_span_c: w.temperature_span_c(),
            mean_table_rate_rad_s: w.mean_table_rate_rad_s(),
        })
        .collect();
    if opts.joint.latitude_deg.is_none() {
        missing.push(
            "no latitude (bench.site latitude_deg): Earth's rotation cannot be removed, so the \
             bias includes it; temperature coefficients are unaffected"
                .into(),
        );
    }
    if !summaries.iter().any(|s| s.kind == WindowKind::Ramp) {
        missing.push(
            "no ramp windows (temperature changing while recording): the seed's k_dt is not \
             estimated"
                .into(),
        );
    }
    (summaries, missing)
}

/// Stage 2: the windows with the model temperature — `series` through the lag when one was
/// found — smoothed, with its rate, over the whole run ([`model_series_windows`]).
fn model_temperature(
    windows: &[RecordWindow],
    series: &TemperatureSeries,
    lag: Option<&Result<LagFit, AnalysisError>>,
    opts: &CalibrateOptions,
) -> Vec<RecordWindow> {
    match lag {
        Some(Ok(l)) if l.used_s > 0.0 => windows_at_lag(windows, series, l.used_s, opts),
        _ => None,
    }
    .unwrap_or_else(|| model_series_windows(windows, series, opts.joint.rate_window_s))
}

/// The windows with the model temperature `series` through a lag of `tau_s`, smoothed and
/// differentiated over the whole run ([`model_series_windows`]); `None` when the lagged series
/// does not fit the windows.
fn windows_at_lag(
    windows: &[RecordWindow],
    series: &TemperatureSeries,
    tau_s: f64,
    opts: &CalibrateOptions,
) -> Option<Vec<RecordWindow>> {
    let lagged = series.lagged(tau_s);
    let w = with_model_series(windows, &lagged).ok()?;
    Some(model_series_windows(&w, &lagged, opts.joint.rate_window_s))
}

/// The model temperature's smoothed value and rate over the whole run (`model_series`), at
/// each window's samples: no filter is cut at a window's edges (a ramp window starts and ends
/// where the temperature bends). Windows keep their own filter when the series does not cover
/// them.
pub fn model_series_windows(
    windows: &[RecordWindow],
    model_series: &TemperatureSeries,
    rate_window_s: f64,
) -> Vec<RecordWindow> {
    let Ok((smooth, rate)) = model_series.smoothed(rate_window_s) else {
        return windows.to_vec();
    };
    let (ss, rs) = (
        TemperatureSeries { time_s: model_series.time_s.clone(), temp_c: smooth },
        TemperatureSeries { time_s: model_series.time_s.clone(), temp_c: rate },
    );
    windows
        .iter()
        .map(|w| {
            let covered = model_series.time_s.first().is_some_and(|&a| a <= w.time_s()[0])
                && model_series.time_s.last().is_some_and(|&b| b >= w.time_s()[w.len() - 1]);
            if covered {
                w.with_smoothed_temperature(ss.sample(w.time_s()), rs.sample(w.time_s()))
                    .unwrap_or_else(|_| w.clone())
            } else {
                w.clone()
            }
        })
        .collect()
}

/// Constant-temperature recording below which the noise model is measured on every window's
/// residual instead, s: 20 min (`thermal-short.toml`'s six 5-min plateaus, 30 min, keep their
/// own curve; a random lab procedure's single 7-min hold before its ramps does not).
const MIN_QUIET_S: f64 = 1200.0;

/// The joint fit's options from the calibration's (no noise model, nothing held).
fn joint_options(opts: &CalibrateOptions) -> JointFitOptions {
    JointFitOptions { noise: None, held: [None; 4], nuisance: None, ..opts.joint.clone() }
}

/// Stage 3: the noise — the overlapping Allan deviation of the thermal model's OLS residual
/// (lag included: a coil still settling on a hold is the model's, not noise), pooled over the
/// windows at constant temperature (else every window), its IEEE 952 terms and the noise
/// model fitted to its curve.
fn noise_stage(
    windows: &[RecordWindow],
    summaries: &[WindowSummary],
    model_windows: &[RecordWindow],
    opts: &CalibrateOptions,
    missing: &mut Vec<String>,
) -> (Result<AllanResult, AnalysisError>, Option<NoiseSpec>, Option<OlsFit>) {
    let ols = ols_fit(model_windows, &joint_options(opts)).ok();
    let quiet: Vec<usize> = (0..windows.len())
        .filter(|&i| {
            summaries[i].kind != WindowKind::Ramp
                && windows[i].temperature_span_c() <= opts.plateau_span_c
        })
        .collect();
    let span = |i: &usize| match (windows[*i].time_s().first(), windows[*i].time_s().last()) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    };
    let quiet_s: f64 = quiet.iter().map(span).sum();
    // Too little constant-temperature time for an Allan curve of its own (a single short hold
    // before the ramps: its few long-τ points read as a rate random walk and inflated σ(k_t)
    // twelvefold on a random null procedure): the residual of every window, which is the
    // thermal model's residual and so fine on ramps too.
    let pooled: Vec<usize> =
        if quiet_s < MIN_QUIET_S { (0..windows.len()).collect() } else { quiet.clone() };
    let allan = match &ols {
        None => Err(AnalysisError::Insufficient(
            "noise: the thermal model cannot be fitted for its residual".into(),
        )),
        Some(o) => {
            let mut start = 0;
            let mut parts: Vec<(&[f64], &[f64])> = Vec::new();
            let mut subs = Vec::new();
            for (i, w) in model_windows.iter().enumerate() {
                if pooled.contains(&i) {
                    parts.push((w.time_s(), &o.residual[start..start + w.len()]));
                    subs.extend(w.sub_block());
                }
                start += w.len();
            }
            // Block means: the octaves below the block from the full-rate samples' sums (the
            // gyro's rate; the model's residual differs from it by what moves over minutes,
            // which a second difference over ≤ n samples removes: `crate::allan_sub`).
            let mut points = crate::allan_sub::sub_block_points(subs);
            points.extend(pooled_adev_series(&parts));
            allan_fit(&points, opts.confidence).map(|fit| AllanResult {
                windows: pooled.iter().map(|&i| windows[i].label().to_owned()).collect(),
                points,
                fit,
            })
        }
    };
    if allan.is_ok()
        && pooled.len() == windows.len()
        && summaries.iter().any(|s| s.kind == WindowKind::Ramp)
    {
        missing.push(if quiet.is_empty() {
            "no constant-temperature windows: the noise model is measured on the thermal \
                 model's residual over the ramps"
                .into()
        } else {
            format!(
                "constant-temperature windows hold {:.0} s, less than the {MIN_QUIET_S:.0} s \
                     an Allan curve needs: the noise model is measured on the thermal model's \
                     residual over every window",
                quiet_s
            )
        });
    }
    let noise = allan.as_ref().ok().map(|a| a.noise(opts.stated_flicker_floor_rad_s));
    if let Some((spec, false)) = noise {
        missing.push(format!(
            "flicker floor: the windows are too short for the Allan deviation to resolve it; \
             the noise model uses {:.3e} °/h ({}), and every σ rests on it — longer holds at \
             constant temperature measure it",
            spec.flicker_floor / bench_physics::units::DEG_PER_H,
            if opts.stated_flicker_floor_rad_s.is_some_and(|b| b >= spec.flicker_floor) {
                "the recording model's bias_instability, the lab's value"
            } else {
                "the largest floor the curve cannot rule out"
            }
        ));
    }
    (allan, noise.map(|(s, _)| s), ols)
}

/// Stage 4: which coefficients the run determines ([`crate::information`]) and the values
/// of those it does not.
fn identify_stage(
    model_windows: &[RecordWindow],
    nuisance: Option<&Nuisance>,
    noise: Option<NoiseSpec>,
    opts: &CalibrateOptions,
) -> (Result<[Determination; 4], AnalysisError>, [Option<HeldCoefficient>; 4]) {
    let info_opts = InformationOptions {
        reference_temperature_c: opts.joint.reference_temperature_c,
        earth_rad_s: opts
            .joint
            .latitude_deg
            .map_or(0.0, |lat| bench_physics::earth::vertical_rate_rad_s(lat, opts.joint.axis_up)),
        rate_window_s: opts.joint.rate_window_s,
        noise,
        expected: opts.expected.map(|e| e.filter(|e| e.sized).map(|e| e.size())),
    };
    let det = identify(model_windows, nuisance, &info_opts);
    let held = match &det {
        Ok(d) => std::array::from_fn(|j| {
            (!d[j].determined()).then(|| {
                let e = opts.expected[j];
                HeldCoefficient {
                    value: e.map_or(0.0, |e| e.value),
                    sigma: e.and_then(|e| e.sigma).unwrap_or(0.0),
                    source: e.map_or(ExpectedSource::None, |e| e.source),
                    determination: d[j],
                }
            })
        }),
        Err(_) => [None; 4],
    };
    (det, held)
}

/// Calibrate from `windows` (time on the same origin as `series`, the whole-run measured
/// temperature); `readings`, one per window (or none), are the table's angle readings over
/// each, for the angle-domain fit.
pub fn calibrate(
    windows: &[RecordWindow],
    readings: &[TableReadings],
    series: &TemperatureSeries,
    opts: &CalibrateOptions,
) -> Calibration {
    let (summaries, mut missing) = classify(windows, opts);
    let ramps = summaries.iter().any(|s| s.kind == WindowKind::Ramp);
    let mut lag = (opts.fit_lag && ramps).then(|| fit_lag(windows, series, opts));
    let model_windows = model_temperature(windows, series, lag.as_ref(), opts);
    let (allan, noise_model, ols) =
        noise_stage(windows, &summaries, &model_windows, opts, &mut missing);
    // A lag found is fitted with the coefficients: its linearised effect is a nuisance column.
    let nuisance = match (&lag, &ols) {
        (Some(Ok(l)), Some(o)) if l.used_s > 0.0 => {
            lag_nuisance(&model_windows, series, l.used_s, o.coefficients, opts.joint.rate_window_s)
        }
        _ => None,
    };
    let (identifiability, held) =
        identify_stage(&model_windows, nuisance.as_ref(), noise_model, opts);
    let joint_opts = JointFitOptions {
        noise: noise_model,
        held: held.map(|h| h.map(|h| Held { value: h.value, sigma: h.sigma })),
        nuisance: nuisance.clone(),
        ..joint_options(opts)
    };
    let joint = joint_fit(&model_windows, &joint_opts);
    let (model_windows, joint_opts, joint) = match &mut lag {
        Some(Ok(l)) => relinearised(windows, series, l, model_windows, joint_opts, joint, opts),
        _ => (model_windows, joint_opts, joint),
    };
    if let Err(e) = &joint {
        missing.push(format!("joint fit: {e}"));
    }
    if let (Some(Ok(l)), Ok(j)) = (&mut lag, &joint) {
        if let Some(e) = &j.nuisance {
            l.gls_shift_s = e.value;
            l.sigma_s =
                lag_sigma_with_held(&model_windows, &joint_opts, &held).unwrap_or(e.std_err);
        }
    }
    let lag_s = match &lag {
        Some(Ok(l)) => l.used_s,
        _ => 0.0,
    };
    let angle =
        angle_stage(readings, &model_windows, &allan, noise_model, &joint_opts, lag_s, opts);
    if let Some(Err(e)) = &angle {
        missing.push(format!("angle-domain fit: {e}"));
    }
    let seed = seed_calibration(
        &model_windows,
        &SeedOptions {
            plateau_span_c: opts.plateau_span_c,
            pair_tolerance_c: opts.pair_tolerance_c,
            reference_temperature_c: opts.joint.reference_temperature_c,
            latitude_deg: opts.joint.latitude_deg,
            axis_up: opts.joint.axis_up,
            rate_window_s: opts.joint.rate_window_s,
        },
    );
    if let Err(e) = &seed {
        missing.push(format!("seed method: {e}"));
    }
    Calibration {
        options: opts.clone(),
        windows: summaries,
        model_windows,
        allan,
        noise_model,
        lag,
        identifiability,
        held,
        seed,
        joint,
        angle,
        missing,
    }
}

/// The lag's σ where a coefficient is held at a nominal value taken as exact: the σ it has
/// with that value uncertain by the σ the run would have given it (its Cramér–Rao bound with
/// the lag free, [`Determination::sigma_bound`]) — the σ of the lag when the held coefficient
/// is not known, which is what a nominal value is.
///
/// A coefficient is held mostly because it trades with the lag (k_dt against k_t·τ: a lag
/// lengthened by Δτ reads as k_dt changed by −k_t·Δτ, the 99 % confounding `identify` finds
/// on short procedures without a sensor); the fit then moves the lag to absorb whatever the
/// held value is off by, and the σ of the lag conditional on that value is far too small. On
/// the lab writer's seed 9 of the coverage study (k_dt held at the nominal 1.21e-5 for a true
/// 1.45e-5) the lag came out 946 ± 40 s for a true 1192 s (−6.1σ); with the held value's
/// uncertainty, ± 598 s (−0.41σ). `None` when nothing is held exactly or the refit fails (the
/// fit's own σ then stands). The coefficients' σ stay conditional on the held value, as the
/// calibration file states it.
fn lag_sigma_with_held(
    model_windows: &[RecordWindow],
    joint_opts: &JointFitOptions,
    held: &[Option<HeldCoefficient>; 4],
) -> Option<f64> {
    let mut any = false;
    let loosened: [Option<Held>; 4] = std::array::from_fn(|j| {
        let h = joint_opts.held[j]?;
        let bound = held[j].as_ref().map_or(f64::NAN, |c| c.determination.sigma_bound);
        if h.sigma > 0.0 || !bound.is_finite() || bound <= 0.0 {
            return Some(h);
        }
        any = true;
        Some(Held { value: h.value, sigma: bound })
    });
    if !any {
        return None;
    }
    let o = JointFitOptions { held: loosened, ..joint_opts.clone() };
    let sigma = joint_fit(model_windows, &o).ok()?.nuisance?.std_err;
    sigma.is_finite().then_some(sigma)
}

/// Most Gauss–Newton steps of the lag ([`relinearised`]).
const LAG_STEPS: usize = 5;

/// A lag step smaller than this share of the lag's σ ends the Gauss–Newton iteration.
const LAG_STEP_TOLERANCE: f64 = 0.05;

/// The joint fit with the lag's nuisance linearised at the lag it fits, not at the profile's
/// τ̂ (Gauss–Newton): while the fit moves τ by more than [`LAG_STEP_TOLERANCE`] of its σ, the
/// model temperature and the nuisance column (`k_t·∂T/∂τ + k_dt·∂Ṫ/∂τ` at the fit's
/// coefficients) are taken again at the moved τ and the coefficients refitted. The profile's τ̂
/// comes from the OLS residual, the fit's τ from the GLS: they differ by about σ(τ), and the
/// first-order column carries the coefficients only part of that way — k_t and k_dt, which
/// the lag trades against each other, keep a bias of their own (on the lab writer's files,
/// largest in the angle domain, whose windows' own reference rates leave k_t to the ramps).
/// `l.used_s` becomes the τ of the last linearisation; the windows, options and fit returned
/// are those at it. A step that fails keeps the fit before it.
fn relinearised(
    windows: &[RecordWindow],
    series: &TemperatureSeries,
    l: &mut LagFit,
    mut model_windows: Vec<RecordWindow>,
    mut joint_opts: JointFitOptions,
    mut joint: Result<JointFit, AnalysisError>,
    opts: &CalibrateOptions,
) -> (Vec<RecordWindow>, JointFitOptions, Result<JointFit, AnalysisError>) {
    if l.used_s <= 0.0 {
        return (model_windows, joint_opts, joint);
    }
    for _ in 0..LAG_STEPS {
        let Ok(j) = &joint else { break };
        let Some(step) = &j.nuisance else { break };
        if !(step.value.is_finite() && step.std_err.is_finite())
            || step.value.abs() <= LAG_STEP_TOLERANCE * step.std_err
        {
            break;
        }
        let tau = (l.used_s + step.value).max(1.0);
        let Some(w) = windows_at_lag(windows, series, tau, opts) else { break };
        let coefficients =
            [j.bias.value, j.scale_factor_error.value, j.temp_coeff.value, j.temp_rate_coeff.value];
        let Some(nu) = lag_nuisance(&w, series, tau, coefficients, opts.joint.rate_window_s) else {
            break;
        };
        let o = JointFitOptions { nuisance: Some(nu), ..joint_opts.clone() };
        let Ok(fit) = joint_fit(&w, &o) else { break };
        l.used_s = tau;
        (model_windows, joint_opts, joint) = (w, o, Ok(fit));
    }
    (model_windows, joint_opts, joint)
}

/// Stage 6: the angle-domain fit (when the table's readings were given), under the same noise
/// model, with the same coefficients held and the lag's nuisance fitted. The model temperature
/// through a lag of `lag_s` is taken as it is when the lag is at least the dT/dt window (a
/// readout step q becomes a ramp of slope q/τ, smoother than the window would make it), else
/// smoothed over that window ([`AngleFitOptions::temp_window_s`]).
fn angle_stage(
    readings: &[TableReadings],
    model_windows: &[RecordWindow],
    allan: &Result<AllanResult, AnalysisError>,
    noise_model: Option<NoiseSpec>,
    joint_opts: &JointFitOptions,
    lag_s: f64,
    opts: &CalibrateOptions,
) -> Option<Result<AngleFit, AnalysisError>> {
    (readings.len() == model_windows.len() && !readings.is_empty()).then(|| {
        let noise = noise_model.ok_or_else(|| match allan {
            Err(e) => e.clone(),
            Ok(_) => AnalysisError::Insufficient("no noise model".into()),
        })?;
        let aws: Vec<_> = readings
            .iter()
            .zip(model_windows)
            .enumerate()
            .map(|(i, (r, w))| AngleWindow {
                nuisance: joint_opts.nuisance.as_ref().map(|n| n.values[i].as_slice()),
                ..r.for_window(w)
            })
            .collect();
        angle_fit(
            &aws,
            &AngleFitOptions {
                reference_temperature_c: opts.joint.reference_temperature_c,
                latitude_deg: opts.joint.latitude_deg,
                axis_up: opts.joint.axis_up,
                noise,
                temp_window_s: (lag_s < opts.joint.rate_window_s)
                    .then_some(opts.joint.rate_window_s),
                held: joint_opts.held.map(|h| h.map(|h| h.value)),
                nuisance: joint_opts.nuisance.is_some(),
            },
        )
    })
}

/// How much of the thermal error a calibration removes, over a temperature series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalErrorRemoval {
    /// RMS of the true thermal error `k_t·(T − T0) + k_dt·dT/dt`, rad/s.
    pub rms_uncalibrated_rad_s: f64,
    /// RMS of what remains after subtracting the fitted bias and thermal terms from the true
    /// ones, rad/s.
    pub rms_calibrated_rad_s: f64,
}

impl ThermalErrorRemoval {
    /// Fraction removed: `1 − rms_calibrated/rms_uncalibrated`.
    pub fn removed(&self) -> f64 {
        1.0 - self.rms_calibrated_rad_s / self.rms_uncalibrated_rad_s
    }
}

/// Thermal bias of `m` at temperature `t` and rate `d`, including the constant bias.
pub fn thermal_bias(m: &GyroModel, t_c: f64, rate_c_s: f64) -> f64 {
    m.bias + m.temp_coeff * (t_c - m.reference_temperature) + m.temp_rate_coeff * rate_c_s
}

/// Compare `fitted` with `truth` along `series` (the gyro temperature over the run): the true
/// thermal error and what remains of it after calibration (bias errors count as remaining).
pub fn thermal_error_removal(
    truth: &GyroModel,
    fitted: &GyroModel,
    series: &TemperatureSeries,
    rate_window_s: f64,
) -> Result<ThermalErrorRemoval, AnalysisError> {
    let rate = local_linear_rate(&series.time_s, &series.temp_c, rate_window_s)?;
    let (mut su, mut sc) = (0.0, 0.0);
    for (t, d) in series.temp_c.iter().zip(&rate) {
        let e = thermal_bias(truth, *t, *d) - truth.bias;
        let r = thermal_bias(truth, *t, *d) - thermal_bias(fitted, *t, *d);
        su += e * e;
        sc += r * r;
    }
    let n = series.temp_c.len() as f64;
    Ok(ThermalErrorRemoval {
        rms_uncalibrated_rad_s: (su / n).sqrt(),
        rms_calibrated_rad_s: (sc / n).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::lag::ramp_response;

    #[test]
    fn a_lagged_ramp_follows_the_closed_form() {
        let time_s: Vec<f64> = (0..2000).map(|i| i as f64 * 0.5).collect();
        let s = TemperatureSeries {
            temp_c: time_s.iter().map(|t| 0.02 * t).collect(),
            time_s: time_s.clone(),
        };
        let l = s.lagged(120.0);
        for (t, y) in time_s.iter().zip(&l.temp_c) {
            assert!((y - ramp_response(120.0, 0.02, *t)).abs() < 1e-9, "{t}");
        }
        assert_eq!(s.sample(&[-1.0, 0.25, 5000.0]), vec![0.0, 0.005, 0.02 * 999.5]);
    }
}
