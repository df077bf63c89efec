//! The seed's calibration method reproduced (`docs/seed-method.md`, stage 3).
//!
//! # Plateaus: K = (k1 + k2)/2
//!
//! A *plateau* is a window whose chamber air stays within `plateau_span_c` — a constant chamber
//! temperature, as in the seed, whose gyro was assumed at air temperature. A gyro still
//! catching up with the air (its own sensor drifting) keeps its plateau; its K then carries
//! the temperature-rate term, the seed's own flaw, reproduced. K is placed at the window's
//! mean model temperature ([`RecordWindow::temperature_c`]). Each CW plateau is paired with the CCW plateau of closest mean
//! temperature, if that is within `pair_tolerance_c` (1 °C by default). For the pair
//!
//! ```text
//! k1 = mean over the CW window  of (V_i − Ω_table,i − Ω_earth)
//! k2 = mean over the CCW window of (V_i − Ω_table,i − Ω_earth)
//! K  = (k1 + k2)/2
//! ```
//!
//! **Sign convention.** The seed writes `k2 = mean(−V_i + …)` because it treats the CCW input
//! as the negated CW input. Taken literally, `(k1 + k2)/2` with `−V_i` would cancel the *bias*
//! and keep the table rate, the opposite of what the seed says it does. What cancels the table
//! rate is subtracting each window's own table rate, as here: then k1 and k2 are both bias
//! estimates, and for `V = Ω·(1 + s) + b(T)` their mean cancels the scale-factor error term
//! `s·Ω` when the two directions have equal speed (`k1 = b − s·ω`, `k2 = b + s·ω`). Equivalently
//! `K = (mean V_cw + mean V_ccw)/2` for equal and opposite table rates. Earth's rotation is
//! subtracted when a latitude is given (the seed ignores it, which puts `Ω_E·sin(lat)`, up to
//! 13 °/h, into every K).
//!
//! # Temperature coefficient: the two-point line
//!
//! The line through the coldest and the warmest plateau `(T_a, K_a)`, `(T_b, K_b)`:
//! `temp_coeff = (K_b − K_a)/(T_b − T_a)`, `bias = K_a + temp_coeff·(T0 − T_a)` at the chosen
//! reference temperature `T0`.
//!
//! # Temperature-rate coefficient: slope through the origin
//!
//! In every non-plateau window with the table turning (a *ramp*), the residual
//! `r_i = V_i − Ω_table,i − Ω_earth − bias − temp_coeff·(T_i − T0)` is regressed on
//! `d_i = dT/dt` ([`crate::temperature_rate::local_linear_rate`] over `rate_window_s`) through
//! the origin: `temp_rate_coeff = Σ r_i·d_i / Σ d_i²`. As in the seed, the scale-factor term is
//! not modelled; it cancels only when CW and CCW ramps are alike.

use bench_physics::earth::vertical_rate_rad_s;
use bench_physics::{GyroModel, ModelKey};

use crate::error::AnalysisError;
use crate::windows::{mean, Direction, RecordWindow};

/// Settings of the seed method.
#[derive(Debug, Clone, PartialEq)]
pub struct SeedOptions {
    /// A window is a plateau when its temperature spread is at most this, °C. Default 1.
    pub plateau_span_c: f64,
    /// Largest difference of mean temperature between paired CW and CCW plateaus, °C. Default 1.
    pub pair_tolerance_c: f64,
    /// Reference temperature T0 of the returned coefficients, °C. Default 20.
    pub reference_temperature_c: f64,
    /// Site latitude (degrees, north positive) for removing Earth's rotation; `None` ignores
    /// it, as the seed does. Default `None`.
    pub latitude_deg: Option<f64>,
    /// Sensing axis points up (the contract's `axis = up`). Default true.
    pub axis_up: bool,
    /// Window of the dT/dt filter, s. Default 60.
    pub rate_window_s: f64,
}

impl Default for SeedOptions {
    fn default() -> Self {
        Self {
            plateau_span_c: 1.0,
            pair_tolerance_c: 1.0,
            reference_temperature_c: 20.0,
            latitude_deg: None,
            axis_up: true,
            rate_window_s: 60.0,
        }
    }
}

/// One CW/CCW plateau pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Plateau {
    /// Label of the CW window.
    pub cw_label: String,
    /// Label of the CCW window.
    pub ccw_label: String,
    /// Mean of the two windows' mean temperatures, °C.
    pub temperature_c: f64,
    /// k1: mean of V − Ω_table (− Ω_earth) over the CW window, rad/s.
    pub k1_rad_s: f64,
    /// k2: the same over the CCW window, rad/s.
    pub k2_rad_s: f64,
    /// K = (k1 + k2)/2, rad/s.
    pub k_rad_s: f64,
}

/// Result of the seed method, in `bench.gyro_model` terms.
#[derive(Debug, Clone, PartialEq)]
pub struct SeedCalibration {
    /// Every CW/CCW pair found, in order of temperature.
    pub plateaus: Vec<Plateau>,
    /// T0, °C.
    pub reference_temperature_c: f64,
    /// Bias at T0, rad/s.
    pub bias_rad_s: f64,
    /// rad/s per °C.
    pub temp_coeff: f64,
    /// rad/s per (°C/s); `None` when no ramp window had a temperature change.
    pub temp_rate_coeff: Option<f64>,
    /// Number of ramp samples used for `temp_rate_coeff`.
    pub ramp_samples: usize,
}

impl SeedCalibration {
    /// The value of a coefficient the method estimates (`None` for the scale factor, which it
    /// cannot tell, and for a temperature-rate coefficient without ramps).
    pub fn coefficient(&self, key: ModelKey) -> Option<f64> {
        match key {
            ModelKey::Bias => Some(self.bias_rad_s),
            ModelKey::TempCoeff => Some(self.temp_coeff),
            ModelKey::TempRateCoeff => self.temp_rate_coeff,
            _ => None,
        }
    }

    /// The calibrated coefficients written over `base` (its noise terms and other keys kept).
    pub fn to_model(&self, base: &GyroModel) -> GyroModel {
        GyroModel {
            bias: self.bias_rad_s,
            reference_temperature: self.reference_temperature_c,
            temp_coeff: self.temp_coeff,
            temp_rate_coeff: self.temp_rate_coeff.unwrap_or(0.0),
            ..base.clone()
        }
    }
}

fn earth(opts: &SeedOptions) -> f64 {
    opts.latitude_deg.map_or(0.0, |lat| vertical_rate_rad_s(lat, opts.axis_up))
}

/// Mean of V − Ω_table − Ω_earth over a window, rad/s.
fn window_bias(w: &RecordWindow, earth_rad_s: f64) -> f64 {
    let d: Vec<f64> = w
        .gyro_rate_rad_s()
        .iter()
        .zip(w.table_rate_rad_s())
        .map(|(v, o)| v - o - earth_rad_s)
        .collect();
    mean(&d)
}

fn is_plateau(w: &RecordWindow, opts: &SeedOptions) -> bool {
    w.chamber_span_c() <= opts.plateau_span_c
}

/// Pair CW and CCW plateaus (module docs); each CCW window is used at most once.
pub fn pair_plateaus(windows: &[RecordWindow], opts: &SeedOptions) -> Vec<Plateau> {
    let e = earth(opts);
    let plateaus: Vec<&RecordWindow> = windows.iter().filter(|w| is_plateau(w, opts)).collect();
    let mut used = vec![false; plateaus.len()];
    let mut out = Vec::new();
    for cw in plateaus.iter().filter(|w| w.direction() == Direction::Cw) {
        let t_cw = cw.mean_temperature_c();
        let best = plateaus
            .iter()
            .enumerate()
            .filter(|(i, w)| !used[*i] && w.direction() == Direction::Ccw)
            .map(|(i, w)| (i, (w.mean_temperature_c() - t_cw).abs()))
            .filter(|&(_, d)| d <= opts.pair_tolerance_c)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, _)) = best {
            used[i] = true;
            let ccw = plateaus[i];
            let k1 = window_bias(cw, e);
            let k2 = window_bias(ccw, e);
            out.push(Plateau {
                cw_label: cw.label().to_owned(),
                ccw_label: ccw.label().to_owned(),
                temperature_c: 0.5 * (t_cw + ccw.mean_temperature_c()),
                k1_rad_s: k1,
                k2_rad_s: k2,
                k_rad_s: 0.5 * (k1 + k2),
            });
        }
    }
    out.sort_by(|a, b| a.temperature_c.total_cmp(&b.temperature_c));
    out
}

/// The seed method over all windows (module docs). Needs at least two plateau pairs at
/// temperatures more than `pair_tolerance_c` apart.
pub fn seed_calibration(
    windows: &[RecordWindow],
    opts: &SeedOptions,
) -> Result<SeedCalibration, AnalysisError> {
    let plateaus = pair_plateaus(windows, opts);
    let (a, b) = match (plateaus.first(), plateaus.last()) {
        (Some(a), Some(b)) if b.temperature_c - a.temperature_c > opts.pair_tolerance_c => (a, b),
        _ => {
            return Err(AnalysisError::Insufficient(format!(
                "the seed method needs CW/CCW plateau pairs at two temperatures more than \
                 {} °C apart; found {} pair(s)",
                opts.pair_tolerance_c,
                plateaus.len()
            )))
        }
    };
    let temp_coeff = (b.k_rad_s - a.k_rad_s) / (b.temperature_c - a.temperature_c);
    let t0 = opts.reference_temperature_c;
    let bias = a.k_rad_s + temp_coeff * (t0 - a.temperature_c);

    let e = earth(opts);
    let (mut srd, mut sdd, mut count) = (0.0, 0.0, 0usize);
    for w in windows.iter().filter(|w| !is_plateau(w, opts) && w.direction() != Direction::Rest) {
        if w.len() < 3 {
            continue;
        }
        let temp = w.temperature_c();
        let rate = w.temperature_rate_c_s(opts.rate_window_s)?;
        for (((v, o), t), d) in
            w.gyro_rate_rad_s().iter().zip(w.table_rate_rad_s()).zip(temp).zip(&rate)
        {
            let r = v - o - e - bias - temp_coeff * (t - t0);
            srd += r * d;
            sdd += d * d;
            count += 1;
        }
    }
    let temp_rate_coeff = (sdd > 0.0).then(|| srd / sdd);
    Ok(SeedCalibration {
        plateaus,
        reference_temperature_c: t0,
        bias_rad_s: bias,
        temp_coeff,
        temp_rate_coeff,
        ramp_samples: if sdd > 0.0 { count } else { 0 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::units::DEG_PER_MIN;

    const DT: f64 = 0.05;
    const OMEGA: f64 = 10.0 * DEG_PER_MIN;

    struct Truth {
        bias: f64,
        sf: f64,
        kt: f64,
        kdt: f64,
        t0: f64,
        earth: f64,
    }

    fn window(
        label: &str,
        table: f64,
        temp: impl Fn(f64) -> f64,
        secs: f64,
        m: &Truth,
    ) -> RecordWindow {
        let n = (secs / DT) as usize;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * DT).collect();
        // Exact temperature derivative by central difference of the smooth profile.
        let h = 1e-3;
        let temps: Vec<f64> = t.iter().map(|&t| temp(t)).collect();
        let v: Vec<f64> = t
            .iter()
            .zip(&temps)
            .map(|(&ti, &tc)| {
                let dtdt = (temp(ti + h) - temp(ti - h)) / (2.0 * h);
                (table + m.earth) * (1.0 + m.sf) + m.bias + m.kt * (tc - m.t0) + m.kdt * dtdt
            })
            .collect();
        RecordWindow::new(label, t, v, vec![table; n], Some(temps.clone()), temps)
            .expect("valid synthetic window")
    }

    fn truth() -> Truth {
        Truth { bias: 3e-6, sf: 2e-4, kt: -1e-7, kdt: 5e-5, t0: 20.0, earth: 0.0 }
    }

    fn bench_windows(m: &Truth) -> Vec<RecordWindow> {
        let ramp = |t: f64| 20.0 + 2.0 / 60.0 * t; // 2 °C/min
        vec![
            window("record cw 20C", -OMEGA, |_| 20.0, 180.0, m),
            window("record ccw 20C", OMEGA, |_| 20.3, 180.0, m),
            window("record cw ramp", -OMEGA, ramp, 600.0, m),
            window("record ccw ramp", OMEGA, ramp, 600.0, m),
            window("record cw 40C", -OMEGA, |_| 40.0, 180.0, m),
            window("record ccw 40C", OMEGA, |_| 39.5, 180.0, m),
        ]
    }

    #[test]
    fn noise_free_coefficients_are_recovered_and_scale_factor_cancels() {
        let m = truth();
        let ws = bench_windows(&m);
        let opts = SeedOptions::default();
        let cal = seed_calibration(&ws, &opts).expect("two plateaus");
        assert_eq!(cal.plateaus.len(), 2);
        let p = &cal.plateaus[0];
        assert_eq!(
            (p.cw_label.as_str(), p.ccw_label.as_str()),
            ("record cw 20C", "record ccw 20C")
        );
        // k1 = b(20.0) − s·ω, k2 = b(20.3) + s·ω: they differ by the scale-factor term (and the
        // pair's 0.3 °C), which K cancels.
        let want = 2.0 * m.sf * OMEGA + m.kt * 0.3;
        assert!((p.k2_rad_s - p.k1_rad_s - want).abs() < 1e-15);
        // The pair's temperatures differ (20.0 vs 20.3): K is b at the mean, 20.15 °C.
        assert!((p.k_rad_s - (m.bias + m.kt * 0.15)).abs() < 1e-15);
        assert!((cal.temp_coeff / m.kt - 1.0).abs() < 1e-9);
        assert!((cal.bias_rad_s - m.bias).abs() < 1e-14);
        // The ramps see ±s·ω which cancels over CW+CCW; dT/dt from the filter is exact on a line
        // except where the window straddles the ramp's ends (none here: the profile is linear).
        let kdt = cal.temp_rate_coeff.expect("ramps present");
        assert!((kdt / m.kdt - 1.0).abs() < 1e-6, "kdt {kdt}");
        assert_eq!(cal.ramp_samples, 2 * 12_000);
        let model = cal.to_model(&GyroModel::zero());
        assert_eq!(model.temp_coeff, cal.temp_coeff);
        assert_eq!(model.reference_temperature, 20.0);
    }

    #[test]
    fn earth_rate_is_removed_only_when_latitude_is_given() {
        let lat = 59.94;
        let m = Truth { earth: vertical_rate_rad_s(lat, true), ..truth() };
        let ws = bench_windows(&m);
        let ignored = seed_calibration(&ws, &SeedOptions::default()).expect("plateaus");
        // Seed's way: Earth rate (×(1+s)) lands in the bias.
        assert!((ignored.bias_rad_s - m.bias - m.earth * (1.0 + m.sf)).abs() < 1e-13);
        let opts = SeedOptions { latitude_deg: Some(lat), ..SeedOptions::default() };
        let removed = seed_calibration(&ws, &opts).expect("plateaus");
        assert!((removed.bias_rad_s - m.bias - m.earth * m.sf).abs() < 1e-13);
    }

    #[test]
    fn reference_temperature_moves_the_bias_along_the_line() {
        let m = truth();
        let ws = bench_windows(&m);
        let opts = SeedOptions { reference_temperature_c: 0.0, ..SeedOptions::default() };
        let cal = seed_calibration(&ws, &opts).expect("plateaus");
        assert!((cal.bias_rad_s - (m.bias - 20.0 * m.kt)).abs() < 1e-13);
    }

    #[test]
    fn one_plateau_or_unpaired_directions_are_an_error() {
        let m = truth();
        let ws = bench_windows(&m);
        // Only the 20 °C pair.
        assert!(matches!(
            seed_calibration(&ws[..2], &SeedOptions::default()),
            Err(AnalysisError::Insufficient(_))
        ));
        // 40 °C CW with 20 °C CCW: more than 1 °C apart, no pair.
        let unpaired = vec![ws[1].clone(), ws[4].clone()];
        assert!(pair_plateaus(&unpaired, &SeedOptions::default()).is_empty());
    }
}
