//! The gyro's output: the truth model that turns the table's motion, Earth's rotation and the
//! gyro's temperature into samples.
//!
//! A sample over `[t − dt, t]` is the mean over that interval of the instantaneous output:
//!
//! ```text
//! input        = s·Δθ_table/dt                       (s = +1 sensing axis up, −1 down)
//! earth        = s·Ω_E·sin(latitude)                 (if model.earth_rate)
//! scale_factor = scale_factor_error·(input + earth)
//! bias         = bias
//! temperature  = temp_coeff·(T̄ − T0)                (T̄: mean gyro temperature, trapezoid rule)
//! temp_rate    = temp_rate_coeff·(T(t) − T(t−dt))/dt (the exact mean of dT/dt)
//! noise        = white (ARW) + bias instability      (see [`crate::noise`])
//! ```
//!
//! with `T` the gyro's own temperature (the payload of [`crate::chamber::ChamberModel`],
//! lagging chamber air by `thermal_time_constant`). The output is the sum of the named terms of
//! [`GyroTerms`]. Effects beyond the model ([`crate::effects`], switched on with
//! [`GyroSampler::with_effects`]) add their term `effects`; `thermal_lag` makes the thermal
//! terms follow `T` through a further lag, and `time_offset` is applied by the caller, which
//! passes the table angle at `t − δ`.

use crate::earth::vertical_rate_rad_s;
use crate::effects::{EffectId, EffectSample, Effects, HysteresisState};
use crate::lag::FirstOrderLag;
use crate::noise::GyroNoise;
use crate::units::quantise;
use crate::GyroModel;

/// Resolution of the gyro's internal temperature readout, °C.
pub const TEMPERATURE_RESOLUTION_C: f64 = 0.01;

/// What the truth model needs for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleInputs {
    /// End of the sample interval, s.
    pub t_end_s: f64,
    /// Length of the sample interval, s.
    pub dt_s: f64,
    /// True angle increment about the sensing axis over the interval, rad (already signed for
    /// the axis direction).
    pub delta_angle_rad: f64,
    /// Earth's rate along the sensing axis, rad/s.
    pub earth_rate_rad_s: f64,
    /// Gyro temperature at the start of the interval, °C.
    pub temp_start_c: f64,
    /// Gyro temperature at the end of the interval, °C.
    pub temp_end_c: f64,
    /// Noise of this sample, rad/s.
    pub noise_rad_s: f64,
}

/// The output of one sample as a sum of named terms, each in rad/s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GyroTerms {
    /// True mean input rate from the table, Δθ/dt.
    pub input: f64,
    /// Earth's rate along the sensing axis (0 if the model leaves it out).
    pub earth: f64,
    /// Scale-factor error applied to the input and Earth rate.
    pub scale_factor: f64,
    /// Constant zero offset.
    pub bias: f64,
    /// Temperature term `temp_coeff·(T̄ − T0)`.
    pub temperature: f64,
    /// Temperature-rate term `temp_rate_coeff·dT/dt`.
    pub temperature_rate: f64,
    /// Effects beyond the model ([`crate::effects`]), 0 without any.
    pub effects: f64,
    /// Noise.
    pub noise: f64,
}

impl GyroTerms {
    /// The gyro's output: the sum of the terms.
    pub fn total(&self) -> f64 {
        self.input
            + self.earth
            + self.scale_factor
            + self.bias
            + self.temperature
            + self.temperature_rate
            + self.effects
            + self.noise
    }

    /// The output without noise.
    pub fn noise_free(&self) -> f64 {
        self.total() - self.noise
    }
}

/// Evaluate the truth model for one sample.
pub fn sample_terms(model: &GyroModel, inp: &SampleInputs) -> GyroTerms {
    let dt = if inp.dt_s > 0.0 { inp.dt_s } else { f64::NAN };
    let input = inp.delta_angle_rad / dt;
    let earth = if model.earth_rate { inp.earth_rate_rad_s } else { 0.0 };
    let t_mean = 0.5 * (inp.temp_start_c + inp.temp_end_c);
    GyroTerms {
        input,
        earth,
        scale_factor: model.scale_factor_error * (input + earth),
        bias: model.bias,
        temperature: model.temp_coeff * (t_mean - model.reference_temperature),
        temperature_rate: model.temp_rate_coeff * (inp.temp_end_c - inp.temp_start_c) / dt,
        effects: 0.0,
        noise: inp.noise_rad_s,
    }
}

/// Where the gyro sits on the bench.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mounting {
    /// Geodetic latitude, degrees north.
    pub latitude_deg: f64,
    /// Sensing axis points up (along the table's counter-clockwise rotation axis).
    pub axis_up: bool,
}

/// A gyro producing successive samples: holds the model, the noise stream and the previous
/// sample's angle and temperature.
#[derive(Debug, Clone)]
pub struct GyroSampler {
    model: GyroModel,
    noise: GyroNoise,
    axis_sign: f64,
    earth_rad_s: f64,
    prev_t_s: f64,
    prev_angle_rad: f64,
    prev_temp_c: f64,
    effects: Effects,
    /// Start of the run (power-on), s.
    t_on_s: f64,
    /// The bias-driving temperature through the effect `thermal_lag` (its previous value).
    coil: FirstOrderLag,
    hysteresis: HysteresisState,
}

impl GyroSampler {
    /// A gyro with truth `model`, samples every `sample_interval_s`, noise from `seed` on ChaCha8
    /// stream `stream`, mounted as `mounting`; it starts at time 0 with the table at angle 0 and
    /// the gyro at `temp0_c` (see [`GyroSampler::starting_at`] for another start).
    pub fn new(
        model: GyroModel,
        sample_interval_s: f64,
        seed: u64,
        stream: u64,
        mounting: Mounting,
        temp0_c: f64,
    ) -> Self {
        let noise = GyroNoise::from_model(&model, sample_interval_s, seed, stream);
        Self {
            model,
            noise,
            axis_sign: if mounting.axis_up { 1.0 } else { -1.0 },
            earth_rad_s: vertical_rate_rad_s(mounting.latitude_deg, mounting.axis_up),
            prev_t_s: 0.0,
            prev_angle_rad: 0.0,
            prev_temp_c: temp0_c,
            effects: Effects::default(),
            t_on_s: 0.0,
            coil: FirstOrderLag::new(0.0, temp0_c),
            hysteresis: HysteresisState::new(Effects::default().hysteresis_threshold_c_s()),
        }
    }

    /// The same gyro with `effects` beyond its model switched on (the truth of a simulation
    /// whose recording keeps them concealed); the coil starts at the gyro's temperature.
    pub fn with_effects(mut self, effects: Effects) -> Self {
        self.coil = FirstOrderLag::new(effects.lag_s(), self.prev_temp_c);
        self.hysteresis = HysteresisState::new(effects.hysteresis_threshold_c_s());
        self.effects = effects;
        self
    }

    /// The effects beyond the model.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// The same gyro starting at time `t0_s` with the table at `angle0_rad` and the gyro at
    /// `temp0_c`.
    pub fn starting_at(mut self, t0_s: f64, angle0_rad: f64, temp0_c: f64) -> Self {
        self.prev_t_s = t0_s;
        self.t_on_s = t0_s;
        self.prev_angle_rad = angle0_rad;
        self.prev_temp_c = temp0_c;
        self.coil = FirstOrderLag::new(self.effects.lag_s(), temp0_c);
        self
    }

    /// The truth model.
    pub fn model(&self) -> &GyroModel {
        &self.model
    }

    /// Change the sample interval of the noise (the next sample's interval is whatever time
    /// passed since the previous one).
    pub fn set_sample_interval(&mut self, sample_interval_s: f64) {
        self.noise.set_sample_interval(sample_interval_s);
    }

    /// The sample over `(previous sample, t_end_s]`, given the table's true angle and the gyro's
    /// true temperature at `t_end_s` (with a `time_offset` effect, the angle at `t_end_s − δ`).
    #[inline]
    pub fn sample(&mut self, t_end_s: f64, table_angle_rad: f64, temp_c: f64) -> GyroTerms {
        let dt_s = t_end_s - self.prev_t_s;
        let (temp_start_c, temp_end_c) = if self.effects.has(EffectId::ThermalLag) {
            let start = self.coil.value();
            (start, self.coil.step_linear(self.prev_temp_c, temp_c, dt_s))
        } else {
            (self.prev_temp_c, temp_c)
        };
        let inp = SampleInputs {
            t_end_s,
            dt_s,
            delta_angle_rad: self.axis_sign * (table_angle_rad - self.prev_angle_rad),
            earth_rate_rad_s: self.earth_rad_s,
            temp_start_c,
            temp_end_c,
            noise_rad_s: self.noise.next_sample(),
        };
        let mut terms = sample_terms(&self.model, &inp);
        if self.effects.any() {
            let earth = if self.model.earth_rate || self.effects.has(EffectId::EarthRate) {
                self.earth_rad_s
            } else {
                0.0
            };
            let rate_c_s = if dt_s > 0.0 { (temp_end_c - temp_start_c) / dt_s } else { 0.0 };
            let s = EffectSample {
                t_s: t_end_s - self.t_on_s,
                input_rad_s: terms.input + earth,
                table_rate_rad_s: terms.input,
                temp_minus_ref_c: 0.5 * (temp_start_c + temp_end_c)
                    - self.model.reference_temperature,
                angle_mid_rad: 0.5 * (table_angle_rad + self.prev_angle_rad),
                hysteresis: self.hysteresis.update(rate_c_s),
                earth_rad_s: self.earth_rad_s,
            };
            terms.effects = self.effects.value(&s, 1.0 + self.model.scale_factor_error);
        }
        self.prev_t_s = t_end_s;
        self.prev_angle_rad = table_angle_rad;
        self.prev_temp_c = temp_c;
        terms
    }

    /// The gyro's temperature readout: `temp_c` quantised to [`TEMPERATURE_RESOLUTION_C`].
    pub fn temperature_readout(temp_c: f64) -> f64 {
        quantise(temp_c, TEMPERATURE_RESOLUTION_C)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chamber::{ChamberModel, ChamberParams};
    use crate::earth::EARTH_RATE_RAD_S;
    use crate::noise::bias_instability_stationary_std;
    use crate::table::{RateTableModel, TableParams};
    use crate::units::{DEG, DEG_PER_H, DEG_PER_MIN};

    const LAT: f64 = 59.94;

    fn model() -> GyroModel {
        GyroModel { bias: 1e-7, scale_factor_error: 1e-4, ..GyroModel::default() }
    }

    /// Bound on the standard deviation of the noise averaged over `t_s`: the white part's
    /// `arw/√t` plus the bias instability's stationary standard deviation (the mean of a
    /// stationary process never varies more than the process).
    fn mean_noise_bound(m: &GyroModel, t_s: f64) -> f64 {
        m.arw / t_s.sqrt() + bias_instability_stationary_std(m.bias_instability)
    }

    #[test]
    fn plateau_output_is_rate_times_scale_factor_plus_bias_and_earth() {
        let m = model();
        for (axis_up, w) in [(true, 10.0 * DEG_PER_MIN), (false, -10.0 * DEG_PER_MIN)] {
            let mut table = RateTableModel::new(TableParams::default());
            table.command_rate(0.0, w, 1.0 * DEG).expect("ok");
            let mut ch = ChamberModel::new(ChamberParams::default(), 40.0, m.thermal_time_constant);
            let mount = Mounting { latitude_deg: LAT, axis_up };
            let dt = 0.05;
            let mut g = GyroSampler::new(m.clone(), dt, 7, 1, mount, 40.0);
            let s = if axis_up { 1.0 } else { -1.0 };
            let earth = s * EARTH_RATE_RAD_S * LAT.to_radians().sin();
            let want = (s * w + earth) * (1.0 + m.scale_factor_error)
                + m.bias
                + m.temp_coeff * (40.0 - 20.0);
            let (n, skip) = (72_000usize, 200usize);
            let (mut sum, mut count) = (0.0, 0usize);
            for k in 1..=n + skip {
                let t = k as f64 * dt;
                let terms = g.sample(t, table.true_angle(t), ch.state(t).payload_c);
                if k > skip {
                    sum += terms.total();
                    count += 1;
                    // Without noise the rate-ripple of the table is the only deviation; it is
                    // bounded by ε·|w|.
                    assert!((terms.noise_free() - want).abs() < 1.01e-5 * w.abs() + 1e-15);
                    assert_eq!(terms.temperature_rate, 0.0);
                }
            }
            let mean = sum / count as f64;
            let tol = 5.0 * mean_noise_bound(&m, count as f64 * dt)
                + 2.0 * 1e-5 / 16.0 / (count as f64 * dt);
            assert!(
                (mean - want).abs() < tol,
                "axis_up={axis_up}: mean {mean:e} want {want:e} tol {tol:e}"
            );
        }
    }

    #[test]
    fn temperature_terms_follow_the_two_lag_ramp_closed_form() {
        let m = GyroModel { arw: 0.0, bias_instability: 0.0, ..model() };
        let (ta, tg) = (120.0, m.thermal_time_constant);
        let s = 2.0 / 60.0;
        let mut ch = ChamberModel::new(ChamberParams::default(), -20.0, tg);
        ch.set_target(0.0, 60.0, Some(s)).expect("ok");
        // Gyro temperature for a ramp through two lags from equilibrium.
        let temp = |t: f64| {
            -20.0
                + s * (t - (ta + tg)
                    + (ta * ta * (-t / ta).exp() - tg * tg * (-t / tg).exp()) / (ta - tg))
        };
        let dt = 0.05;
        let mount = Mounting { latitude_deg: LAT, axis_up: true };
        let mut g = GyroSampler::new(m.clone(), dt, 1, 1, mount, -20.0);
        let table = RateTableModel::new(TableParams::default());
        let earth = EARTH_RATE_RAD_S * LAT.to_radians().sin() * (1.0 + m.scale_factor_error);
        for k in 1..=40_000 {
            let t = k as f64 * dt;
            let st = ch.state(t);
            assert!((st.payload_c - temp(t)).abs() < 1e-9, "t={t}");
            let terms = g.sample(t, table.true_angle(t), st.payload_c);
            let rate_want = m.temp_rate_coeff * (temp(t) - temp(t - dt)) / dt;
            assert!((terms.temperature_rate - rate_want).abs() < 1e-9 * m.temp_rate_coeff);
            let t_mean = 0.5 * (temp(t) + temp(t - dt));
            assert!(
                (terms.temperature - m.temp_coeff * (t_mean - 20.0)).abs() < 1e-9 * m.temp_coeff
            );
            assert!(
                (terms.total() - (earth + m.bias + terms.temperature + terms.temperature_rate))
                    .abs()
                    < 1e-18
            );
        }
        // Late in the ramp dT/dt → s: the rate term is temp_rate_coeff·s (0.06 °/h here).
        let t = 2000.0;
        let terms = g.sample(t + dt, 0.0, ch.state(t + dt).payload_c);
        let settled = 1.0 - (ta * (-t / ta).exp() - tg * (-t / tg).exp()) / (ta - tg);
        assert!((terms.temperature_rate / (m.temp_rate_coeff * s) - settled).abs() < 1e-3);
        assert!(terms.temperature_rate / DEG_PER_H > 0.05);
    }

    #[test]
    fn temperature_readout_has_0_01_c_resolution() {
        assert_eq!(GyroSampler::temperature_readout(21.234_9), 21.23);
        assert_eq!(GyroSampler::temperature_readout(-3.996), -4.0);
    }
}
