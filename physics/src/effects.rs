//! FOG effects beyond the nominal error model ([`crate::GyroModel`]): the library that the
//! simulator switches on as hidden truth and that `bench diagnose` fits to a recording's
//! residual. One definition serves both: the simulator adds [`Effects::value`], the analysis
//! builds its regressors from [`EffectId::regressors`] — the same functions.
//!
//! Every effect is a sum of linear parameters times regressors, given its nonlinear parameters
//! (a time constant, a time, an offset); the regressors are functions of an [`EffectSample`]:
//!
//! | effect | output added, rad/s | linear | nonlinear |
//! | --- | --- | --- | --- |
//! | `earth_rate` | `(1 + s)·Ω_E·sin(lat)` though the model leaves Earth out | 1 (×Ω_E sin lat) | — |
//! | `thermal_lag` | the thermal terms driven by `T_c`, the sensor temperature through a lag τ | — (the model's k_t, k_dt) | τ |
//! | `temperature_quadratic` | `c₂·(T − T0)²` | c₂ | — |
//! | `scale_factor_temperature` | `k_sT·(T − T0)·Ω_in` | k_sT | — |
//! | `thermal_hysteresis` | `h·m`, m = +1 after heating, −1 after cooling, 0 before either | h | threshold |
//! | `once_per_revolution` | `a·sin(θ + φ)`, θ the table angle | a·cos φ, a·sin φ | — |
//! | `time_offset` | input over `[t − dt − δ, t − δ]` instead of `[t − dt, t]` | — | δ |
//! | `warm_up` | `A·e^{−(t − t_on)/τ}` | A | τ |
//! | `bias_step` | `b·H(t − t_s)` | b | t_s |
//! | `rate_squared` | `c·Ω_in²` | c | — |
//! | `periodic_bias` | `a·sin(2π·t/P + φ)` | a·cos φ, a·sin φ | P |
//! | `rate_ripple` | `ε·Ω_t·sin(N·θ + φ)`, Ω_t the table's rate along the sensing axis | ε·cos φ, ε·sin φ | N |
//! | `angle_harmonic` | `a·sin(k·θ + φ)`, k ≥ 2 cycles per revolution, independent of the rate | a·cos φ, a·sin φ | k |
//!
//! `Ω_in` is the input rate the gyro sees (table plus Earth along the sensing axis), `T` the
//! temperature that drives the bias (°C), `t` seconds since power-on (the start of the run; in
//! a recording, the first message).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::lag::FirstOrderLag;

/// The effects of the library, by their stable ids (JSON, TOML, docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectId {
    /// Earth's rotation that the nominal model leaves out.
    EarthRate,
    /// Gyro coil temperature lagging the temperature the model uses.
    ThermalLag,
    /// Bias quadratic in temperature.
    TemperatureQuadratic,
    /// Scale factor that changes with temperature.
    ScaleFactorTemperature,
    /// Bias that depends on whether the gyro last heated or cooled.
    ThermalHysteresis,
    /// Output periodic in the table angle, once per revolution.
    OncePerRevolution,
    /// Gyro time tags offset from the table's.
    TimeOffset,
    /// Bias decaying exponentially after power-on.
    WarmUp,
    /// Sudden bias change at one instant.
    BiasStep,
    /// Output proportional to the square of the input rate.
    RateSquared,
    /// Bias oscillating in time with a period of its own.
    PeriodicBias,
    /// Table rate rippling N times per revolution, below the table's readout resolution.
    RateRipple,
    /// Output periodic in the table angle, k ≥ 2 times per revolution (the gyro's, not the
    /// table's rate: independent of how fast the table turns).
    AngleHarmonic,
}

impl EffectId {
    /// Every effect, in library order.
    pub const ALL: [EffectId; 13] = [
        EffectId::EarthRate,
        EffectId::ThermalLag,
        EffectId::TemperatureQuadratic,
        EffectId::ScaleFactorTemperature,
        EffectId::ThermalHysteresis,
        EffectId::OncePerRevolution,
        EffectId::TimeOffset,
        EffectId::WarmUp,
        EffectId::BiasStep,
        EffectId::RateSquared,
        EffectId::PeriodicBias,
        EffectId::RateRipple,
        EffectId::AngleHarmonic,
    ];

    /// The stable id (snake case).
    pub fn key(self) -> &'static str {
        match self {
            EffectId::EarthRate => "earth_rate",
            EffectId::ThermalLag => "thermal_lag",
            EffectId::TemperatureQuadratic => "temperature_quadratic",
            EffectId::ScaleFactorTemperature => "scale_factor_temperature",
            EffectId::ThermalHysteresis => "thermal_hysteresis",
            EffectId::OncePerRevolution => "once_per_revolution",
            EffectId::TimeOffset => "time_offset",
            EffectId::WarmUp => "warm_up",
            EffectId::BiasStep => "bias_step",
            EffectId::RateSquared => "rate_squared",
            EffectId::PeriodicBias => "periodic_bias",
            EffectId::RateRipple => "rate_ripple",
            EffectId::AngleHarmonic => "angle_harmonic",
        }
    }

    /// The effect with id `key`.
    pub fn from_key(key: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.key() == key)
    }

    /// One line of physics.
    pub fn description(self) -> &'static str {
        match self {
            EffectId::EarthRate => {
                "Earth's rotation along the sensing axis (Ω_E·sin latitude), left out of the model"
            }
            EffectId::ThermalLag => {
                "the fibre coil's temperature lags the measured temperature by a first-order \
                 time constant, so the thermal bias follows the temperature late"
            }
            EffectId::TemperatureQuadratic => {
                "bias curves with temperature: a term in (T − T0)² beside the linear one"
            }
            EffectId::ScaleFactorTemperature => {
                "scale factor changes with temperature (source wavelength, coil length): an \
                 error ∝ rate × (T − T0) that flips sign with the direction of rotation"
            }
            EffectId::ThermalHysteresis => {
                "bias differs after heating and after cooling (stress in the coil potting \
                 relaxes with the direction of the last temperature change)"
            }
            EffectId::OncePerRevolution => {
                "output periodic once per table revolution: a tilted sensing axis picking up \
                 the horizontal Earth rate, or magnetic (Faraday) sensitivity"
            }
            EffectId::TimeOffset => {
                "gyro and table time tags are offset: the gyro's rate is compared with the \
                 table's motion at the wrong instant, spiking at every rate change"
            }
            EffectId::WarmUp => {
                "bias settling exponentially after power-on as the source and electronics warm"
            }
            EffectId::BiasStep => "a sudden bias jump at one instant (mode hop, shock, reset)",
            EffectId::RateSquared => {
                "output error ∝ rate² (scale-factor asymmetry / nonlinearity), the same for \
                 both directions"
            }
            EffectId::PeriodicBias => {
                "bias oscillating in time with a period unrelated to the table or the test \
                 profile: environment cycling (lab air conditioning, the chamber's compressor, \
                 nearby equipment) reaching the gyro or its electronics"
            }
            EffectId::RateRipple => {
                "the table's rate ripples N times per revolution (torque-motor cogging, encoder \
                 errors) by less than its angle readout resolves: the gyro sees ε·Ω·sin(Nθ + φ) \
                 that the recorded table motion does not show"
            }
            EffectId::AngleHarmonic => {
                "output periodic k ≥ 2 times per table revolution whatever the rate: the \
                 gyro's own angle-dependent error (an asymmetric mount or magnetic shield, a \
                 field gradient across the table) rather than the table's rate ripple"
            }
        }
    }
}

/// Thermal lag: the bias terms follow the temperature through a first-order lag.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalLag {
    /// Time constant, s (> 0).
    pub time_constant_s: f64,
}

/// Bias quadratic in temperature.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureQuadratic {
    /// `c₂`, rad/s per °C².
    pub coeff_rad_s_per_c2: f64,
}

/// Scale factor linear in temperature.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleFactorTemperature {
    /// `k_sT`, per °C (dimensionless scale-factor error per °C).
    pub coeff_per_c: f64,
}

/// Heating/cooling hysteresis of the bias.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalHysteresis {
    /// `h`: the bias is `+h` after heating, `−h` after cooling, rad/s.
    pub half_width_rad_s: f64,
    /// |dT/dt| above which the state follows the direction of the change, °C/s.
    pub threshold_c_s: f64,
}

/// Default hysteresis threshold: 0.1 °C/min.
pub const HYSTERESIS_THRESHOLD_C_S: f64 = 0.1 / 60.0;

/// Once-per-revolution term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OncePerRevolution {
    /// `a`, rad/s.
    pub amplitude_rad_s: f64,
    /// `φ` in `a·sin(θ + φ)`, rad.
    pub phase_rad: f64,
}

/// Time-tag offset of the gyro against the table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeOffset {
    /// `δ`, s: positive when the gyro's time tags are late (its sample stamped `t` describes
    /// the motion up to `t − δ`).
    pub offset_s: f64,
}

/// Warm-up transient after power-on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WarmUp {
    /// `A` at power-on, rad/s.
    pub amplitude_rad_s: f64,
    /// Decay time constant, s (> 0).
    pub time_constant_s: f64,
}

/// A bias step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BiasStep {
    /// When, s since power-on.
    pub time_s: f64,
    /// Size, rad/s.
    pub step_rad_s: f64,
}

/// Rate-squared term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RateSquared {
    /// `c`, rad/s per (rad/s)², i.e. s/rad.
    pub coeff_s_per_rad: f64,
}

/// Bias oscillating in time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeriodicBias {
    /// `a`, rad/s.
    pub amplitude_rad_s: f64,
    /// `P`, s (> 0).
    pub period_s: f64,
    /// `φ` in `a·sin(2π·t/P + φ)`, rad (t from power-on).
    pub phase_rad: f64,
}

/// Rate ripple of the table at N cycles per revolution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RateRipple {
    /// `ε`: the ripple's amplitude relative to the table's rate (dimensionless).
    pub relative_amplitude: f64,
    /// `N`, cycles per revolution (> 0; an integer for a table).
    pub cycles_per_rev: f64,
    /// `φ` in `ε·Ω_t·sin(N·θ + φ)`, rad.
    pub phase_rad: f64,
}

/// Output periodic in the table angle at k ≥ 2 cycles per revolution.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AngleHarmonic {
    /// `a`, rad/s.
    pub amplitude_rad_s: f64,
    /// `k`, cycles per revolution (> 0; an integer: 1 is `once_per_revolution`).
    pub cycles_per_rev: f64,
    /// `φ` in `a·sin(k·θ + φ)`, rad.
    pub phase_rad: f64,
}

/// The effects switched on (truth of a simulator, or found by a diagnosis); all off by default.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Effects {
    /// Add Earth's rate even though the model's `earth_rate` is off.
    pub earth_rate: bool,
    /// See [`ThermalLag`].
    pub thermal_lag: Option<ThermalLag>,
    /// See [`TemperatureQuadratic`].
    pub temperature_quadratic: Option<TemperatureQuadratic>,
    /// See [`ScaleFactorTemperature`].
    pub scale_factor_temperature: Option<ScaleFactorTemperature>,
    /// See [`ThermalHysteresis`].
    pub thermal_hysteresis: Option<ThermalHysteresis>,
    /// See [`OncePerRevolution`].
    pub once_per_revolution: Option<OncePerRevolution>,
    /// See [`TimeOffset`].
    pub time_offset: Option<TimeOffset>,
    /// See [`WarmUp`].
    pub warm_up: Option<WarmUp>,
    /// See [`BiasStep`].
    pub bias_step: Option<BiasStep>,
    /// See [`RateSquared`].
    pub rate_squared: Option<RateSquared>,
    /// See [`PeriodicBias`].
    pub periodic_bias: Option<PeriodicBias>,
    /// See [`RateRipple`].
    pub rate_ripple: Option<RateRipple>,
    /// See [`AngleHarmonic`].
    pub angle_harmonic: Option<AngleHarmonic>,
}

/// What the additive effects depend on, for one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EffectSample {
    /// End of the sample interval, s since power-on.
    pub t_s: f64,
    /// Input rate along the sensing axis (table plus Earth), rad/s.
    pub input_rad_s: f64,
    /// The table's rate along the sensing axis (no Earth), rad/s.
    pub table_rate_rad_s: f64,
    /// `T − T0` of the temperature that drives the bias, °C.
    pub temp_minus_ref_c: f64,
    /// Table angle at the middle of the sample interval, rad.
    pub angle_mid_rad: f64,
    /// Hysteresis state (see [`HysteresisState`]): +1, −1 or 0.
    pub hysteresis: f64,
    /// Earth's rate along the sensing axis, rad/s.
    pub earth_rad_s: f64,
}

impl EffectId {
    /// How many linear parameters the effect has.
    pub fn linear_count(self) -> usize {
        match self {
            EffectId::ThermalLag | EffectId::TimeOffset => 0,
            EffectId::OncePerRevolution
            | EffectId::PeriodicBias
            | EffectId::RateRipple
            | EffectId::AngleHarmonic => 2,
            _ => 1,
        }
    }

    /// The effect's regressors for one sample, given its nonlinear parameter `p` (warm-up time
    /// constant, bias-step time, period, cycles per revolution; ignored by the others); writes [`Self::linear_count`] values.
    /// Effects that transform the inputs (thermal lag, time offset) have none: they are applied
    /// to the inputs instead ([`lag_temperature`], the time-shifted table angle).
    pub fn regressors(self, s: &EffectSample, p: f64, out: &mut [f64]) {
        match self {
            EffectId::EarthRate => out[0] = s.earth_rad_s,
            EffectId::TemperatureQuadratic => out[0] = s.temp_minus_ref_c * s.temp_minus_ref_c,
            EffectId::ScaleFactorTemperature => out[0] = s.temp_minus_ref_c * s.input_rad_s,
            EffectId::ThermalHysteresis => out[0] = s.hysteresis,
            EffectId::OncePerRevolution => {
                let (sin, cos) = s.angle_mid_rad.sin_cos();
                out[0] = sin;
                out[1] = cos;
            }
            EffectId::WarmUp => out[0] = if p > 0.0 { (-s.t_s / p).exp() } else { 0.0 },
            EffectId::BiasStep => out[0] = if s.t_s >= p { 1.0 } else { 0.0 },
            EffectId::RateSquared => out[0] = s.input_rad_s * s.input_rad_s,
            EffectId::PeriodicBias => {
                let (sin, cos) = if p > 0.0 {
                    (std::f64::consts::TAU * s.t_s / p).sin_cos()
                } else {
                    (0.0, 0.0)
                };
                out[0] = sin;
                out[1] = cos;
            }
            EffectId::RateRipple => {
                let (sin, cos) = (p * s.angle_mid_rad).sin_cos();
                out[0] = s.table_rate_rad_s * sin;
                out[1] = s.table_rate_rad_s * cos;
            }
            EffectId::AngleHarmonic => {
                let (sin, cos) = (p * s.angle_mid_rad).sin_cos();
                out[0] = sin;
                out[1] = cos;
            }
            EffectId::ThermalLag | EffectId::TimeOffset => {}
        }
    }
}

impl Effects {
    /// Whether any effect is on.
    pub fn any(&self) -> bool {
        *self != Effects::default()
    }

    /// The ids of the effects that are on, in library order.
    pub fn ids(&self) -> Vec<EffectId> {
        EffectId::ALL.into_iter().filter(|&e| self.has(e)).collect()
    }

    /// Whether effect `id` is on.
    pub fn has(&self, id: EffectId) -> bool {
        match id {
            EffectId::EarthRate => self.earth_rate,
            EffectId::ThermalLag => self.thermal_lag.is_some(),
            EffectId::TemperatureQuadratic => self.temperature_quadratic.is_some(),
            EffectId::ScaleFactorTemperature => self.scale_factor_temperature.is_some(),
            EffectId::ThermalHysteresis => self.thermal_hysteresis.is_some(),
            EffectId::OncePerRevolution => self.once_per_revolution.is_some(),
            EffectId::TimeOffset => self.time_offset.is_some(),
            EffectId::WarmUp => self.warm_up.is_some(),
            EffectId::BiasStep => self.bias_step.is_some(),
            EffectId::RateSquared => self.rate_squared.is_some(),
            EffectId::PeriodicBias => self.periodic_bias.is_some(),
            EffectId::RateRipple => self.rate_ripple.is_some(),
            EffectId::AngleHarmonic => self.angle_harmonic.is_some(),
        }
    }

    /// Check every parameter: finite, time constants and the hysteresis threshold positive.
    /// The error names the parameter (`effect.parameter`) and says what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let mut checks: Vec<(&str, f64, bool)> = Vec::new();
        if let Some(l) = self.thermal_lag {
            checks.push(("thermal_lag.time_constant_s", l.time_constant_s, true));
        }
        if let Some(q) = self.temperature_quadratic {
            checks.push(("temperature_quadratic.coeff_rad_s_per_c2", q.coeff_rad_s_per_c2, false));
        }
        if let Some(k) = self.scale_factor_temperature {
            checks.push(("scale_factor_temperature.coeff_per_c", k.coeff_per_c, false));
        }
        if let Some(h) = self.thermal_hysteresis {
            checks.push(("thermal_hysteresis.half_width_rad_s", h.half_width_rad_s, false));
            checks.push(("thermal_hysteresis.threshold_c_s", h.threshold_c_s, true));
        }
        if let Some(o) = self.once_per_revolution {
            checks.push(("once_per_revolution.amplitude_rad_s", o.amplitude_rad_s, false));
            checks.push(("once_per_revolution.phase_rad", o.phase_rad, false));
        }
        if let Some(o) = self.time_offset {
            checks.push(("time_offset.offset_s", o.offset_s, false));
        }
        if let Some(w) = self.warm_up {
            checks.push(("warm_up.amplitude_rad_s", w.amplitude_rad_s, false));
            checks.push(("warm_up.time_constant_s", w.time_constant_s, true));
        }
        if let Some(b) = self.bias_step {
            checks.push(("bias_step.time_s", b.time_s, false));
            checks.push(("bias_step.step_rad_s", b.step_rad_s, false));
        }
        if let Some(c) = self.rate_squared {
            checks.push(("rate_squared.coeff_s_per_rad", c.coeff_s_per_rad, false));
        }
        if let Some(b) = self.periodic_bias {
            checks.push(("periodic_bias.amplitude_rad_s", b.amplitude_rad_s, false));
            checks.push(("periodic_bias.period_s", b.period_s, true));
            checks.push(("periodic_bias.phase_rad", b.phase_rad, false));
        }
        if let Some(r) = self.rate_ripple {
            checks.push(("rate_ripple.relative_amplitude", r.relative_amplitude, false));
            checks.push(("rate_ripple.cycles_per_rev", r.cycles_per_rev, true));
            checks.push(("rate_ripple.phase_rad", r.phase_rad, false));
        }
        if let Some(h) = self.angle_harmonic {
            checks.push(("angle_harmonic.amplitude_rad_s", h.amplitude_rad_s, false));
            checks.push(("angle_harmonic.cycles_per_rev", h.cycles_per_rev, true));
            checks.push(("angle_harmonic.phase_rad", h.phase_rad, false));
        }
        for (name, v, positive) in checks {
            if !v.is_finite() {
                return Err(format!("`{name}` must be a finite number, got {v}"));
            }
            if positive && v <= 0.0 {
                return Err(format!("`{name}` must be positive, got {v}"));
            }
        }
        Ok(())
    }

    /// Lag time constant of the bias-driving temperature, s (0 without `thermal_lag`).
    pub fn lag_s(&self) -> f64 {
        self.thermal_lag.map_or(0.0, |l| l.time_constant_s)
    }

    /// Time-tag offset, s (0 without `time_offset`).
    pub fn offset_s(&self) -> f64 {
        self.time_offset.map_or(0.0, |o| o.offset_s)
    }

    /// Hysteresis threshold, °C/s (the default without `thermal_hysteresis`).
    pub fn hysteresis_threshold_c_s(&self) -> f64 {
        self.thermal_hysteresis.map_or(HYSTERESIS_THRESHOLD_C_S, |h| h.threshold_c_s)
    }

    /// The additive effects' output for one sample, rad/s; `scale` is `1 + scale_factor_error`
    /// (Earth's rate passes through the scale factor like any input).
    pub fn value(&self, s: &EffectSample, scale: f64) -> f64 {
        let mut v = 0.0;
        let mut r = [0.0; 2];
        let mut term = |id: EffectId, p: f64, coeffs: [f64; 2]| {
            id.regressors(s, p, &mut r);
            (0..id.linear_count()).map(|k| coeffs[k] * r[k]).sum::<f64>()
        };
        if self.earth_rate {
            v += term(EffectId::EarthRate, 0.0, [scale, 0.0]);
        }
        if let Some(q) = self.temperature_quadratic {
            v += term(EffectId::TemperatureQuadratic, 0.0, [q.coeff_rad_s_per_c2, 0.0]);
        }
        if let Some(k) = self.scale_factor_temperature {
            v += term(EffectId::ScaleFactorTemperature, 0.0, [k.coeff_per_c, 0.0]);
        }
        if let Some(h) = self.thermal_hysteresis {
            v += term(EffectId::ThermalHysteresis, 0.0, [h.half_width_rad_s, 0.0]);
        }
        // `A·sin(x + φ)` = `A cos φ·sin x + A sin φ·cos x`.
        let wave = |amp: f64, phase: f64| {
            let (sp, cp) = phase.sin_cos();
            [amp * cp, amp * sp]
        };
        if let Some(o) = self.once_per_revolution {
            v += term(EffectId::OncePerRevolution, 0.0, wave(o.amplitude_rad_s, o.phase_rad));
        }
        if let Some(w) = self.warm_up {
            v += term(EffectId::WarmUp, w.time_constant_s, [w.amplitude_rad_s, 0.0]);
        }
        if let Some(b) = self.bias_step {
            v += term(EffectId::BiasStep, b.time_s, [b.step_rad_s, 0.0]);
        }
        if let Some(c) = self.rate_squared {
            v += term(EffectId::RateSquared, 0.0, [c.coeff_s_per_rad, 0.0]);
        }
        if let Some(b) = self.periodic_bias {
            v += term(EffectId::PeriodicBias, b.period_s, wave(b.amplitude_rad_s, b.phase_rad));
        }
        if let Some(r) = self.rate_ripple {
            let coeffs = wave(r.relative_amplitude, r.phase_rad);
            v += term(EffectId::RateRipple, r.cycles_per_rev, coeffs);
        }
        if let Some(h) = self.angle_harmonic {
            let coeffs = wave(h.amplitude_rad_s, h.phase_rad);
            v += term(EffectId::AngleHarmonic, h.cycles_per_rev, coeffs);
        }
        v
    }
}

/// Heating/cooling memory: +1 once dT/dt rose above the threshold, −1 once it fell below minus
/// the threshold, unchanged in between (0 before either).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HysteresisState {
    threshold_c_s: f64,
    state: f64,
}

impl HysteresisState {
    /// A virgin state with threshold `threshold_c_s` (°C/s, > 0).
    pub fn new(threshold_c_s: f64) -> Self {
        Self { threshold_c_s: threshold_c_s.abs(), state: 0.0 }
    }

    /// Update with the rate of temperature change now (°C/s); returns the state.
    #[inline]
    pub fn update(&mut self, rate_c_s: f64) -> f64 {
        if rate_c_s > self.threshold_c_s {
            self.state = 1.0;
        } else if rate_c_s < -self.threshold_c_s {
            self.state = -1.0;
        }
        self.state
    }

    /// The state over a whole series of rates.
    pub fn series(threshold_c_s: f64, rates_c_s: &[f64]) -> Vec<f64> {
        let mut h = Self::new(threshold_c_s);
        rates_c_s.iter().map(|&r| h.update(r)).collect()
    }
}

/// The temperature series `temp_c` at times `time_s` through a first-order lag of `tau_s`,
/// linear between samples, starting in equilibrium with the first value.
pub fn lag_temperature(time_s: &[f64], temp_c: &[f64], tau_s: f64) -> Vec<f64> {
    let Some(&first) = temp_c.first() else { return Vec::new() };
    let mut lag = FirstOrderLag::new(tau_s, first);
    let mut out = Vec::with_capacity(temp_c.len());
    out.push(first);
    for k in 1..temp_c.len() {
        out.push(lag.step_linear(temp_c[k - 1], temp_c[k], time_s[k] - time_s[k - 1]));
    }
    out
}

/// Prefix of the effects' keys in `bench.gyro_model` metadata (`effect.<id>.<parameter>`).
pub const METADATA_PREFIX: &str = "effect.";

impl EffectId {
    /// The effect's parameter names, SI with the unit in the name, in the order of its struct's
    /// fields (empty for `earth_rate`, which is on or off). The same names serve scenario
    /// tables, model files and `bench.gyro_model` metadata keys.
    pub fn params(self) -> &'static [&'static str] {
        match self {
            EffectId::EarthRate => &[],
            EffectId::ThermalLag => &["time_constant_s"],
            EffectId::TemperatureQuadratic => &["coeff_rad_s_per_c2"],
            EffectId::ScaleFactorTemperature => &["coeff_per_c"],
            EffectId::ThermalHysteresis => &["half_width_rad_s", "threshold_c_s"],
            EffectId::OncePerRevolution => &["amplitude_rad_s", "phase_rad"],
            EffectId::TimeOffset => &["offset_s"],
            EffectId::WarmUp => &["amplitude_rad_s", "time_constant_s"],
            EffectId::BiasStep => &["time_s", "step_rad_s"],
            EffectId::RateSquared => &["coeff_s_per_rad"],
            EffectId::PeriodicBias => &["amplitude_rad_s", "period_s", "phase_rad"],
            EffectId::RateRipple => &["relative_amplitude", "cycles_per_rev", "phase_rad"],
            EffectId::AngleHarmonic => &["amplitude_rad_s", "cycles_per_rev", "phase_rad"],
        }
    }

    /// Which of [`Self::params`] must be greater than zero (the rest must only be finite).
    pub fn param_must_be_positive(self, param: &str) -> bool {
        matches!(
            (self, param),
            (EffectId::ThermalLag, "time_constant_s")
                | (EffectId::WarmUp, "time_constant_s")
                | (EffectId::ThermalHysteresis, "threshold_c_s")
                | (EffectId::PeriodicBias, "period_s")
                | (EffectId::RateRipple, "cycles_per_rev")
                | (EffectId::AngleHarmonic, "cycles_per_rev")
        )
    }
}

impl Effects {
    /// The parameters of effect `id` in [`EffectId::params`] order, `None` when it is off
    /// (`earth_rate` on gives an empty list).
    pub fn param_values(&self, id: EffectId) -> Option<Vec<f64>> {
        match id {
            EffectId::EarthRate => self.earth_rate.then(Vec::new),
            EffectId::ThermalLag => self.thermal_lag.map(|e| vec![e.time_constant_s]),
            EffectId::TemperatureQuadratic => {
                self.temperature_quadratic.map(|e| vec![e.coeff_rad_s_per_c2])
            }
            EffectId::ScaleFactorTemperature => {
                self.scale_factor_temperature.map(|e| vec![e.coeff_per_c])
            }
            EffectId::ThermalHysteresis => {
                self.thermal_hysteresis.map(|e| vec![e.half_width_rad_s, e.threshold_c_s])
            }
            EffectId::OncePerRevolution => {
                self.once_per_revolution.map(|e| vec![e.amplitude_rad_s, e.phase_rad])
            }
            EffectId::TimeOffset => self.time_offset.map(|e| vec![e.offset_s]),
            EffectId::WarmUp => self.warm_up.map(|e| vec![e.amplitude_rad_s, e.time_constant_s]),
            EffectId::BiasStep => self.bias_step.map(|e| vec![e.time_s, e.step_rad_s]),
            EffectId::RateSquared => self.rate_squared.map(|e| vec![e.coeff_s_per_rad]),
            EffectId::PeriodicBias => {
                self.periodic_bias.map(|e| vec![e.amplitude_rad_s, e.period_s, e.phase_rad])
            }
            EffectId::RateRipple => {
                self.rate_ripple.map(|e| vec![e.relative_amplitude, e.cycles_per_rev, e.phase_rad])
            }
            EffectId::AngleHarmonic => {
                self.angle_harmonic.map(|e| vec![e.amplitude_rad_s, e.cycles_per_rev, e.phase_rad])
            }
        }
    }

    /// Switch effect `id` on with `values` in [`EffectId::params`] order (replacing it if it
    /// was on). Values are not checked here ([`Self::validate`] does); a wrong count is an
    /// error naming the effect.
    pub fn set(&mut self, id: EffectId, values: &[f64]) -> Result<(), String> {
        let want = id.params().len();
        if values.len() != want {
            return Err(format!(
                "effect `{}` takes {want} parameter(s) ({}), got {}",
                id.key(),
                id.params().join(", "),
                values.len()
            ));
        }
        let v = |k: usize| values[k];
        match id {
            EffectId::EarthRate => self.earth_rate = true,
            EffectId::ThermalLag => {
                self.thermal_lag = Some(ThermalLag { time_constant_s: v(0) });
            }
            EffectId::TemperatureQuadratic => {
                self.temperature_quadratic =
                    Some(TemperatureQuadratic { coeff_rad_s_per_c2: v(0) });
            }
            EffectId::ScaleFactorTemperature => {
                self.scale_factor_temperature = Some(ScaleFactorTemperature { coeff_per_c: v(0) });
            }
            EffectId::ThermalHysteresis => {
                self.thermal_hysteresis =
                    Some(ThermalHysteresis { half_width_rad_s: v(0), threshold_c_s: v(1) });
            }
            EffectId::OncePerRevolution => {
                self.once_per_revolution =
                    Some(OncePerRevolution { amplitude_rad_s: v(0), phase_rad: v(1) });
            }
            EffectId::TimeOffset => self.time_offset = Some(TimeOffset { offset_s: v(0) }),
            EffectId::WarmUp => {
                self.warm_up = Some(WarmUp { amplitude_rad_s: v(0), time_constant_s: v(1) });
            }
            EffectId::BiasStep => {
                self.bias_step = Some(BiasStep { time_s: v(0), step_rad_s: v(1) });
            }
            EffectId::RateSquared => {
                self.rate_squared = Some(RateSquared { coeff_s_per_rad: v(0) });
            }
            EffectId::PeriodicBias => {
                self.periodic_bias =
                    Some(PeriodicBias { amplitude_rad_s: v(0), period_s: v(1), phase_rad: v(2) });
            }
            EffectId::RateRipple => {
                self.rate_ripple = Some(RateRipple {
                    relative_amplitude: v(0),
                    cycles_per_rev: v(1),
                    phase_rad: v(2),
                });
            }
            EffectId::AngleHarmonic => {
                self.angle_harmonic = Some(AngleHarmonic {
                    amplitude_rad_s: v(0),
                    cycles_per_rev: v(1),
                    phase_rad: v(2),
                });
            }
        }
        Ok(())
    }

    /// Switch effect `id` off.
    pub fn clear(&mut self, id: EffectId) {
        match id {
            EffectId::EarthRate => self.earth_rate = false,
            EffectId::ThermalLag => self.thermal_lag = None,
            EffectId::TemperatureQuadratic => self.temperature_quadratic = None,
            EffectId::ScaleFactorTemperature => self.scale_factor_temperature = None,
            EffectId::ThermalHysteresis => self.thermal_hysteresis = None,
            EffectId::OncePerRevolution => self.once_per_revolution = None,
            EffectId::TimeOffset => self.time_offset = None,
            EffectId::WarmUp => self.warm_up = None,
            EffectId::BiasStep => self.bias_step = None,
            EffectId::RateSquared => self.rate_squared = None,
            EffectId::PeriodicBias => self.periodic_bias = None,
            EffectId::RateRipple => self.rate_ripple = None,
            EffectId::AngleHarmonic => self.angle_harmonic = None,
        }
    }

    /// As extra `bench.gyro_model` metadata keys: `effect.<id>.<parameter>` for every parameter
    /// of every effect that is on, numbers as decimal text in the shortest form that reads back
    /// exactly (`{:e}`), and `effect.earth_rate` = `1` when that effect is on. Effects that are
    /// off have no keys.
    pub fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut m = BTreeMap::new();
        for id in EffectId::ALL {
            let Some(values) = self.param_values(id) else { continue };
            if id == EffectId::EarthRate {
                m.insert(format!("{METADATA_PREFIX}{}", id.key()), "1".to_string());
            }
            for (p, v) in id.params().iter().zip(values) {
                m.insert(format!("{METADATA_PREFIX}{}.{p}", id.key()), format!("{v:e}"));
            }
        }
        m
    }

    /// From `bench.gyro_model` metadata: reads exactly the keys [`Self::to_metadata`] writes and
    /// ignores every other key. An effect is on when any of its keys is present; then all of
    /// them must be. `effect.earth_rate` takes `1`/`0` (or `true`/`false`). Errors name the key
    /// (unparsable value, missing sibling parameter). Values are not range-checked here; call
    /// [`Self::validate`] before simulating them.
    pub fn from_metadata(meta: &BTreeMap<String, String>) -> Result<Effects, String> {
        let mut out = Effects::default();
        for id in EffectId::ALL {
            let base = format!("{METADATA_PREFIX}{}", id.key());
            if id == EffectId::EarthRate {
                if let Some(v) = meta.get(&base) {
                    out.earth_rate = match v.trim() {
                        "1" | "true" => true,
                        "0" | "false" => false,
                        other => {
                            return Err(format!(
                                "`{base}` must be 1 or 0 (true or false), got \"{other}\""
                            ))
                        }
                    };
                }
                continue;
            }
            let keys: Vec<String> = id.params().iter().map(|p| format!("{base}.{p}")).collect();
            if !keys.iter().any(|k| meta.contains_key(k)) {
                continue;
            }
            let mut values = Vec::with_capacity(keys.len());
            for k in &keys {
                let Some(text) = meta.get(k) else {
                    let given = keys.iter().find(|g| meta.contains_key(*g)).map_or("", |g| g);
                    return Err(format!("`{k}` is missing (`{given}` is given)"));
                };
                let v = text
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| format!("`{k}` must be a number, got \"{text}\""))?;
                values.push(v);
            }
            out.set(id, &values)?;
        }
        Ok(out)
    }

    /// These effects with each effect that is on in `over` replacing or adding to them (the
    /// rule for a simulator's truth: the nominal effects, overridden per effect).
    pub fn overridden_by(&self, over: &Effects) -> Effects {
        let mut out = *self;
        for id in over.ids() {
            if let Some(values) = over.param_values(id) {
                // `values` comes from `over` itself, so the count always fits.
                let _ = out.set(id, &values);
            }
        }
        out
    }
}

#[cfg(test)]
mod metadata_tests {
    use super::*;
    use proptest::prelude::*;

    fn every_effect() -> Effects {
        Effects {
            earth_rate: true,
            thermal_lag: Some(ThermalLag { time_constant_s: 312.5 }),
            temperature_quadratic: Some(TemperatureQuadratic { coeff_rad_s_per_c2: 2.1e-11 }),
            scale_factor_temperature: Some(ScaleFactorTemperature { coeff_per_c: -3e-7 }),
            thermal_hysteresis: Some(ThermalHysteresis {
                half_width_rad_s: 4e-9,
                threshold_c_s: HYSTERESIS_THRESHOLD_C_S,
            }),
            once_per_revolution: Some(OncePerRevolution {
                amplitude_rad_s: 2e-8,
                phase_rad: 0.1 + 0.2,
            }),
            time_offset: Some(TimeOffset { offset_s: -0.0125 }),
            warm_up: Some(WarmUp { amplitude_rad_s: 1e-7, time_constant_s: 900.0 }),
            bias_step: Some(BiasStep { time_s: 100.0, step_rad_s: 1e-6 }),
            rate_squared: Some(RateSquared { coeff_s_per_rad: 1.0 / 3.0 }),
            periodic_bias: Some(PeriodicBias {
                amplitude_rad_s: 5e-8,
                period_s: 1234.5,
                phase_rad: -0.7,
            }),
            rate_ripple: Some(RateRipple {
                relative_amplitude: 1e-5,
                cycles_per_rev: 16.0,
                phase_rad: 0.25,
            }),
            angle_harmonic: Some(AngleHarmonic {
                amplitude_rad_s: 6e-8,
                cycles_per_rev: 2.0,
                phase_rad: -0.4,
            }),
        }
    }

    #[test]
    fn params_match_the_struct_field_names() {
        // The metadata and scenario names are the structs' field names (serde uses them too).
        let e = every_effect();
        let toml_like = format!("{e:?}");
        for id in EffectId::ALL {
            for p in id.params() {
                assert!(toml_like.contains(&format!("{p}:")), "{p} of {}", id.key());
            }
            assert_eq!(e.param_values(id).map(|v| v.len()), Some(id.params().len()));
        }
    }

    #[test]
    fn metadata_keys_and_values_are_the_documented_ones() {
        let m = every_effect().to_metadata();
        assert_eq!(m.get("effect.earth_rate").map(String::as_str), Some("1"));
        assert_eq!(
            m.get("effect.once_per_revolution.amplitude_rad_s").map(String::as_str),
            Some("2e-8")
        );
        assert_eq!(m.get("effect.bias_step.time_s").map(String::as_str), Some("1e2"));
        assert_eq!(m.get("effect.warm_up.time_constant_s").map(String::as_str), Some("9e2"));
        // 1 + every parameter of the twelve parametrised effects.
        assert_eq!(m.len(), 1 + 22);
        assert!(m.keys().all(|k| k.starts_with(METADATA_PREFIX)));
        assert!(Effects::default().to_metadata().is_empty());
    }

    #[test]
    fn metadata_round_trips_exactly_and_ignores_other_keys() {
        let e = every_effect();
        let mut m = e.to_metadata();
        m.insert("bias".into(), "1e-8".into());
        m.insert("effect.unknown_thing.x".into(), "zzz".into());
        m.insert("effect.warm_up.colour".into(), "blue".into());
        assert_eq!(Effects::from_metadata(&m), Ok(e));
        for id in EffectId::ALL {
            let mut one = Effects::default();
            one.set(id, &e.param_values(id).expect("on")).expect("count fits");
            assert_eq!(Effects::from_metadata(&one.to_metadata()), Ok(one), "{}", id.key());
        }
        assert_eq!(Effects::from_metadata(&BTreeMap::new()), Ok(Effects::default()));
    }

    #[test]
    fn bad_metadata_names_the_key() {
        let mut m = every_effect().to_metadata();
        m.insert("effect.warm_up.time_constant_s".into(), "soon".into());
        let e = Effects::from_metadata(&m).expect_err("unparsable");
        assert!(e.contains("`effect.warm_up.time_constant_s`") && e.contains("soon"), "{e}");
        let mut m = every_effect().to_metadata();
        m.remove("effect.bias_step.step_rad_s");
        let e = Effects::from_metadata(&m).expect_err("incomplete");
        assert!(e.starts_with("`effect.bias_step.step_rad_s` is missing"), "{e}");
        let mut m = BTreeMap::new();
        m.insert("effect.earth_rate".to_string(), "yes".to_string());
        let e = Effects::from_metadata(&m).expect_err("not a flag");
        assert!(e.contains("`effect.earth_rate`"), "{e}");
    }

    #[test]
    fn set_checks_the_count_and_overrides_replace_per_effect() {
        let mut e = Effects::default();
        assert!(e.set(EffectId::WarmUp, &[1.0]).is_err());
        e.set(EffectId::WarmUp, &[1e-7, 60.0]).expect("fits");
        e.set(EffectId::RateSquared, &[2e-3]).expect("fits");
        let mut over = Effects::default();
        over.set(EffectId::WarmUp, &[2e-7, 30.0]).expect("fits");
        over.earth_rate = true;
        let t = e.overridden_by(&over);
        assert_eq!(t.warm_up, Some(WarmUp { amplitude_rad_s: 2e-7, time_constant_s: 30.0 }));
        assert_eq!(t.rate_squared, e.rate_squared);
        assert!(t.earth_rate);
        let mut cleared = t;
        cleared.clear(EffectId::WarmUp);
        assert!(!cleared.has(EffectId::WarmUp) && cleared.has(EffectId::RateSquared));
    }

    fn finite() -> impl Strategy<Value = f64> {
        prop_oneof![
            any::<f64>().prop_filter("finite", |x| x.is_finite()),
            -1e3..1e3f64,
            Just(0.0),
            Just(-0.0),
            Just(f64::MIN_POSITIVE),
        ]
    }

    proptest! {
        #[test]
        fn any_finite_effects_round_trip_exactly(
            on in proptest::collection::vec(any::<bool>(), EffectId::ALL.len()),
            values in proptest::collection::vec(finite(), 3 * EffectId::ALL.len()),
        ) {
            let mut e = Effects::default();
            for (k, id) in EffectId::ALL.into_iter().enumerate() {
                if on[k] {
                    let n = id.params().len();
                    e.set(id, &values[3 * k..3 * k + n]).expect("count fits");
                }
            }
            let back = Effects::from_metadata(&e.to_metadata()).expect("parses");
            // Bitwise: -0.0 must stay -0.0.
            for id in EffectId::ALL {
                let a = e.param_values(id).map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
                let b = back.param_values(id).map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
                prop_assert_eq!(a, b);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_round_trip_and_descriptions_are_one_line() {
        for id in EffectId::ALL {
            assert_eq!(EffectId::from_key(id.key()), Some(id));
            assert!(!id.description().contains('\n'));
        }
        assert_eq!(EffectId::from_key("nope"), None);
    }

    #[test]
    fn value_matches_the_closed_forms() {
        let s = EffectSample {
            t_s: 100.0,
            input_rad_s: 0.003,
            table_rate_rad_s: 0.0029,
            temp_minus_ref_c: -10.0,
            angle_mid_rad: 0.7,
            hysteresis: -1.0,
            earth_rad_s: 6.3e-5,
        };
        let one = |e: Effects| e.value(&s, 1.001);
        let eff = Effects::default();
        assert_eq!(one(eff), 0.0);
        assert_eq!(one(Effects { earth_rate: true, ..eff }), 6.3e-5 * 1.001);
        let q = TemperatureQuadratic { coeff_rad_s_per_c2: 2e-11 };
        assert_eq!(one(Effects { temperature_quadratic: Some(q), ..eff }), 2e-11 * 100.0);
        let k = ScaleFactorTemperature { coeff_per_c: 1e-6 };
        assert!((one(Effects { scale_factor_temperature: Some(k), ..eff }) + 3e-8).abs() < 1e-22);
        let h = ThermalHysteresis { half_width_rad_s: 4e-9, threshold_c_s: 1e-3 };
        assert_eq!(one(Effects { thermal_hysteresis: Some(h), ..eff }), -4e-9);
        let o = OncePerRevolution { amplitude_rad_s: 2e-8, phase_rad: 0.3 };
        let got = one(Effects { once_per_revolution: Some(o), ..eff });
        assert!((got - 2e-8 * (0.7f64 + 0.3).sin()).abs() < 1e-22);
        let w = WarmUp { amplitude_rad_s: 1e-7, time_constant_s: 50.0 };
        let got = one(Effects { warm_up: Some(w), ..eff });
        assert!((got - 1e-7 * (-2.0f64).exp()).abs() < 1e-22);
        let b = |t| Effects { bias_step: Some(BiasStep { time_s: t, step_rad_s: 3e-9 }), ..eff };
        assert_eq!(one(b(100.0)), 3e-9);
        assert_eq!(one(b(100.1)), 0.0);
        let c = RateSquared { coeff_s_per_rad: 1e-3 };
        assert!((one(Effects { rate_squared: Some(c), ..eff }) - 9e-9).abs() < 1e-22);
        let pb = PeriodicBias { amplitude_rad_s: 4e-8, period_s: 800.0, phase_rad: -0.4 };
        let got = one(Effects { periodic_bias: Some(pb), ..eff });
        // 100 s of an 800 s period: a quarter of π on.
        let want = 4e-8 * (std::f64::consts::FRAC_PI_4 - 0.4).sin();
        assert!((got - want).abs() < 1e-22, "{got} vs {want}");
        let rr = RateRipple { relative_amplitude: 1e-5, cycles_per_rev: 16.0, phase_rad: 0.2 };
        let got = one(Effects { rate_ripple: Some(rr), ..eff });
        let want = 1e-5 * 0.0029 * (16.0f64 * 0.7 + 0.2).sin();
        assert!((got - want).abs() < 1e-22, "{got} vs {want}");
    }

    #[test]
    fn hysteresis_remembers_the_last_direction() {
        let r = [0.0, 1e-4, 2e-3, 0.0, -1e-4, -5e-3, 0.0, 1e-3];
        assert_eq!(HysteresisState::series(1e-3, &r), vec![0., 0., 1., 1., 1., -1., -1., -1.]);
    }

    #[test]
    fn lagged_ramp_trails_by_rate_times_tau() {
        let t: Vec<f64> = (0..20_000).map(|k| k as f64 * 0.5).collect();
        let temp: Vec<f64> = t.iter().map(|t| 0.01 * t).collect();
        let lagged = lag_temperature(&t, &temp, 300.0);
        let last = lagged.len() - 1;
        // After 33 time constants the lag is rate·τ = 3 °C to rounding.
        assert!((temp[last] - lagged[last] - 3.0).abs() < 1e-9);
        assert_eq!(lag_temperature(&t, &temp, 0.0), temp);
    }
}
