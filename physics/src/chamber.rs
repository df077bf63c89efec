//! Climatic chamber: the controller's working set point ramps to the target at a limited rate,
//! the air follows the working set point through a first-order lag with heating and cooling
//! slew limits, and a payload (the gyro's sensing coil) follows the air through a second lag.
//!
//! # Model
//!
//! ```text
//! working set point  sp: ramps toward the target at ≤ max heat / cool rate, then holds
//! air                a:  da/dt = clamp((sp − a)/τ_air, −cool_slew, +heat_slew)
//! payload            g:  dg/dt = (a − g)/τ_payload
//! ```
//!
//! The set point is piecewise linear, so between breakpoints (a command, the set point reaching
//! the target, the air's slew limit starting or ceasing to bind) the air is either linear
//! (slew-limited) or `p0 + p1·u + D·e^{−u/τ_air}`, and the payload is the closed-form response of
//! the lag to that. Breakpoints are solved in closed form when a segment starts, so the state at
//! any instant is an exact, pure function of the commands given so far: it does not depend on
//! when or how often it is evaluated. `τ = 0` makes a stage follow its input exactly.

use rand::Rng;
use rand_distr::StandardNormal;

use crate::units::quantise;

/// Chamber parameters. Defaults: the ST1300's climatic chamber.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChamberParams {
    /// Lowest target, °C (default −55).
    pub min_temp_c: f64,
    /// Highest target, °C (default +185).
    pub max_temp_c: f64,
    /// Fastest heating ramp of the working set point, °C/s (default 5 °C/min).
    pub max_heat_rate_c_s: f64,
    /// Fastest cooling ramp of the working set point, °C/s, positive (default 3.5 °C/min).
    pub max_cool_rate_c_s: f64,
    /// Time constant of the air following the working set point, s (default 120).
    pub air_time_constant_s: f64,
    /// Fastest heating of the air, °C/s (default 5 °C/min, as the set-point ramp).
    pub air_heat_slew_c_s: f64,
    /// Fastest cooling of the air, °C/s, positive (default 3.5 °C/min).
    pub air_cool_slew_c_s: f64,
    /// Resolution of the process value and displayed set point, °C (default 0.1).
    pub resolution_c: f64,
    /// Standard deviation of the air sensor's noise, °C (default 0.01).
    pub sensor_noise_c: f64,
}

impl Default for ChamberParams {
    fn default() -> Self {
        Self {
            min_temp_c: -55.0,
            max_temp_c: 185.0,
            max_heat_rate_c_s: 5.0 / 60.0,
            max_cool_rate_c_s: 3.5 / 60.0,
            air_time_constant_s: 120.0,
            air_heat_slew_c_s: 5.0 / 60.0,
            air_cool_slew_c_s: 3.5 / 60.0,
            resolution_c: 0.1,
            sensor_noise_c: 0.01,
        }
    }
}

/// A rejected chamber command.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChamberError {
    /// Target outside the chamber's range (or not finite).
    #[error("target {target_c} °C is outside the chamber's range {min_c}..{max_c} °C")]
    TargetOutOfRange {
        /// The target.
        target_c: f64,
        /// Lowest allowed.
        min_c: f64,
        /// Highest allowed.
        max_c: f64,
    },
    /// Ramp not positive or not finite.
    #[error("ramp {ramp_c_s} °C/s must be a positive number")]
    BadRamp {
        /// The ramp.
        ramp_c_s: f64,
    },
    /// A command was given at a time before an earlier one.
    #[error("command at t = {t_s} s is before the previous command at {previous_s} s")]
    TimeReversed {
        /// Time of this command, s.
        t_s: f64,
        /// Time of the previous command, s.
        previous_s: f64,
    },
}

/// True thermal state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermalState {
    /// Time, s.
    pub time_s: f64,
    /// Target set point, °C.
    pub target_c: f64,
    /// Working set point, °C.
    pub setpoint_c: f64,
    /// Working set point's rate, °C/s.
    pub setpoint_rate_c_s: f64,
    /// Air temperature, °C.
    pub air_c: f64,
    /// Air temperature's rate, °C/s.
    pub air_rate_c_s: f64,
    /// Payload (gyro) temperature, °C.
    pub payload_c: f64,
    /// Payload temperature's rate, °C/s (exact, from the lag's equation).
    pub payload_rate_c_s: f64,
    /// The working set point is ramping.
    pub ramping: bool,
    /// The air's heating or cooling slew limit binds.
    pub saturated: bool,
}

/// What the controller reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChamberReadout {
    /// Process value: air temperature plus sensor noise, quantised, °C.
    pub temperature_c: f64,
    /// Working set point, quantised, °C.
    pub setpoint_c: f64,
    /// Target, °C.
    pub target_c: f64,
}

#[derive(Debug, Clone, Copy)]
struct Segment {
    t0: f64,
    end: f64,
    target: f64,
    ramp_up: f64,
    ramp_down: f64,
    sp0: f64,
    s: f64,
    sp_end: f64,
    // air(u) = p0 + p1·u + d·e^{−u/τ_air}
    p0: f64,
    p1: f64,
    d: f64,
    clamped: bool,
    g0: f64,
}

/// Segments kept for looking back in time.
const KEEP_SEGMENTS: usize = 256;
/// Relative tolerance when deciding whether a slew limit binds.
const SLEW_TOL: f64 = 1e-9;

/// The chamber's thermal plant with a lagged payload.
#[derive(Debug, Clone)]
pub struct ChamberModel {
    params: ChamberParams,
    tau_air: f64,
    tau_payload: f64,
    segments: Vec<Segment>,
}

fn clean_tau(t: f64) -> f64 {
    if t.is_finite() && t > 0.0 {
        t
    } else {
        0.0
    }
}

impl ChamberModel {
    /// A chamber at rest at time 0: target, set point, air and payload all at `initial_c`;
    /// the payload follows the air with time constant `payload_tau_s` (0 = at air temperature).
    pub fn new(params: ChamberParams, initial_c: f64, payload_tau_s: f64) -> Self {
        let tau_air = clean_tau(params.air_time_constant_s);
        let mut me =
            Self { params, tau_air, tau_payload: clean_tau(payload_tau_s), segments: Vec::new() };
        let (up, down) = (me.params.max_heat_rate_c_s, me.params.max_cool_rate_c_s);
        let seg = me.build(0.0, initial_c, initial_c, up, down, initial_c, initial_c);
        me.segments.push(seg);
        me
    }

    /// The parameters.
    pub fn params(&self) -> &ChamberParams {
        &self.params
    }

    /// Set a new target at time `t_s`: the working set point ramps to it from where it is at
    /// `ramp_c_s` (magnitude, °C/s; clamped to the heating or cooling capability) or, for
    /// `None`, at the capability. Returns the ramp actually used in the direction of travel.
    pub fn set_target(
        &mut self,
        t_s: f64,
        target_c: f64,
        ramp_c_s: Option<f64>,
    ) -> Result<f64, ChamberError> {
        let p = &self.params;
        if !target_c.is_finite() || target_c < p.min_temp_c || target_c > p.max_temp_c {
            return Err(ChamberError::TargetOutOfRange {
                target_c,
                min_c: p.min_temp_c,
                max_c: p.max_temp_c,
            });
        }
        let (up, down) = match ramp_c_s {
            None => (p.max_heat_rate_c_s, p.max_cool_rate_c_s),
            Some(r) if r.is_finite() && r > 0.0 => {
                (r.min(p.max_heat_rate_c_s), r.min(p.max_cool_rate_c_s))
            }
            Some(r) => return Err(ChamberError::BadRamp { ramp_c_s: r }),
        };
        let previous_s = self.segments.last().map_or(0.0, |s| s.t0);
        if !t_s.is_finite() || t_s < previous_s {
            return Err(ChamberError::TimeReversed { t_s, previous_s });
        }
        let st = self.state(t_s);
        if let Some(last) = self.segments.last_mut() {
            last.end = t_s;
        }
        let seg = self.build(t_s, st.setpoint_c, target_c, up, down, st.air_c, st.payload_c);
        if self.segments.len() >= KEEP_SEGMENTS {
            self.segments.drain(..KEEP_SEGMENTS / 2);
        }
        self.segments.push(seg);
        Ok(if target_c >= st.setpoint_c { up } else { down })
    }

    /// Start a segment at `t0` and solve for its end (the next breakpoint).
    #[allow(clippy::too_many_arguments)]
    fn build(
        &self,
        t0: f64,
        sp0: f64,
        target: f64,
        ramp_up: f64,
        ramp_down: f64,
        a0: f64,
        g0: f64,
    ) -> Segment {
        let s = if target > sp0 {
            ramp_up
        } else if target < sp0 {
            -ramp_down
        } else {
            0.0
        };
        let sp_dur = if s != 0.0 { (target - sp0) / s } else { f64::INFINITY };
        let tau = self.tau_air;
        let (p0, p1, d, clamped, phase_dur);
        if tau == 0.0 {
            (p0, p1, d, clamped, phase_dur) = (sp0, s, 0.0, false, f64::INFINITY);
        } else {
            let h = self.params.air_heat_slew_c_s;
            let c = -self.params.air_cool_slew_c_s;
            let r0 = (sp0 - a0) / tau;
            let heat = r0 > h * (1.0 + SLEW_TOL) || (s > h && r0 >= h * (1.0 - SLEW_TOL));
            let cool = r0 < c * (1.0 + SLEW_TOL) || (s < c && r0 <= c * (1.0 - SLEW_TOL));
            if heat || cool {
                let lim = if heat { h } else { c };
                // The gap sp − a changes at s − lim; the limit stops binding when it reaches lim·τ.
                let dur = if (heat && s < h) || (cool && s > c) {
                    (sp0 - a0 - lim * tau) / (lim - s)
                } else {
                    f64::INFINITY
                };
                (p0, p1, d, clamped, phase_dur) = (a0, lim, 0.0, true, dur);
            } else {
                // Lag of the ramp: rate goes monotonically from r0 to s; if s is beyond a limit,
                // the rate reaches the limit at u = −τ·ln((lim − s)/(r0 − s)).
                let dur = if s > h {
                    -tau * ((h - s) / (r0 - s)).ln()
                } else if s < c {
                    -tau * ((c - s) / (r0 - s)).ln()
                } else {
                    f64::INFINITY
                };
                (p0, p1, d, clamped, phase_dur) =
                    (sp0 - s * tau, s, a0 - sp0 + s * tau, false, dur);
            }
        }
        let mut dur = sp_dur.min(phase_dur);
        if dur.is_nan() || dur <= 0.0 {
            dur = f64::INFINITY;
        }
        Segment {
            t0,
            end: t0 + dur,
            target,
            ramp_up,
            ramp_down,
            sp0,
            s,
            sp_end: t0 + sp_dur,
            p0,
            p1,
            d,
            clamped,
            g0,
        }
    }

    /// State `u` seconds into `seg`.
    #[inline]
    fn eval(&self, seg: &Segment, u: f64) -> ThermalState {
        let u = u.max(0.0);
        let sp = seg.sp0 + seg.s * u;
        let (ta, tg) = (self.tau_air, self.tau_payload);
        let (air, air_rate, ea) = if seg.d != 0.0 && ta > 0.0 {
            let ea = (-u / ta).exp();
            (seg.p0 + seg.p1 * u + seg.d * ea, seg.p1 - seg.d / ta * ea, ea)
        } else {
            (seg.p0 + seg.p1 * u, seg.p1, 0.0)
        };
        let (g, g_rate) = if tg == 0.0 {
            (air, air_rate)
        } else {
            let eg = (-u / tg).exp();
            let base0 = seg.p0 - seg.p1 * tg;
            let e = seg.g0 - base0;
            let mut g = base0 + seg.p1 * u + e * eg;
            if seg.d != 0.0 && ta > 0.0 {
                // Lag of D·e^{−u/τa}: D·τa/(τa−τg)·(e^{−u/τa} − e^{−u/τg}), written stably
                // for τa → τg as D·e^{−u/τg}·(u/τg)·expm1(x)/x, x = u·(τa−τg)/(τa·τg).
                let h = if (ta - tg).abs() > 1e-6 * ta.max(tg) {
                    ta / (ta - tg) * (ea - eg)
                } else {
                    let x = u * (ta - tg) / (ta * tg);
                    let r = if x.abs() < 1e-8 { 1.0 + 0.5 * x } else { x.exp_m1() / x };
                    eg * (u / tg) * r
                };
                g += seg.d * h;
            }
            (g, (air - g) / tg)
        };
        ThermalState {
            time_s: seg.t0 + u,
            target_c: seg.target,
            setpoint_c: sp,
            setpoint_rate_c_s: seg.s,
            air_c: air,
            air_rate_c_s: air_rate,
            payload_c: g,
            payload_rate_c_s: g_rate,
            ramping: seg.s != 0.0,
            saturated: seg.clamped,
        }
    }

    /// Generate the segments that start at breakpoints up to `t_s`.
    fn extend_to(&mut self, t_s: f64) {
        for _ in 0..64 {
            let Some(last) = self.segments.last().copied() else {
                return;
            };
            if last.end.is_nan() || last.end > t_s {
                return;
            }
            let mut st = self.eval(&last, last.end - last.t0);
            if last.end >= last.sp_end {
                st.setpoint_c = last.target;
            }
            if self.tau_air == 0.0 {
                st.air_c = st.setpoint_c;
            }
            let seg = self.build(
                last.end,
                st.setpoint_c,
                last.target,
                last.ramp_up,
                last.ramp_down,
                st.air_c,
                st.payload_c,
            );
            if self.segments.len() >= KEEP_SEGMENTS {
                self.segments.drain(..KEEP_SEGMENTS / 2);
            }
            self.segments.push(seg);
        }
    }

    /// Exact state at `t_s` (which may be before the last command, within the kept history).
    pub fn state(&mut self, t_s: f64) -> ThermalState {
        self.extend_to(t_s);
        let seg =
            self.segments.iter().rev().find(|s| s.t0 <= t_s).or(self.segments.first()).copied();
        match seg {
            Some(seg) => self.eval(&seg, t_s - seg.t0),
            // Unreachable: there is always at least one segment.
            None => ThermalState {
                time_s: t_s,
                target_c: f64::NAN,
                setpoint_c: f64::NAN,
                setpoint_rate_c_s: 0.0,
                air_c: f64::NAN,
                air_rate_c_s: 0.0,
                payload_c: f64::NAN,
                payload_rate_c_s: 0.0,
                ramping: false,
                saturated: false,
            },
        }
    }

    /// Controller readout of `state`: process value with sensor noise from `rng`, quantised.
    pub fn readout<R: Rng + ?Sized>(&self, state: &ThermalState, rng: &mut R) -> ChamberReadout {
        let mut pv = state.air_c;
        if self.params.sensor_noise_c > 0.0 {
            let n: f64 = rng.sample(StandardNormal);
            pv += self.params.sensor_noise_c * n;
        }
        ChamberReadout {
            temperature_c: quantise(pv, self.params.resolution_c),
            setpoint_c: quantise(state.setpoint_c, self.params.resolution_c),
            target_c: state.target_c,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn quiet() -> ChamberParams {
        ChamberParams { sensor_noise_c: 0.0, ..ChamberParams::default() }
    }

    #[test]
    fn set_point_ramp_is_limited_and_air_trails_by_rate_tau() {
        let mut ch = ChamberModel::new(quiet(), 20.0, 0.0);
        // Ask for 10 °C/min: heating is limited to 5 °C/min.
        let used = ch.set_target(100.0, 60.0, Some(10.0 / 60.0)).expect("accepted");
        let s = 5.0 / 60.0;
        assert_eq!(used, s);
        let tau = 120.0;
        let t_reach = 100.0 + 40.0 / s; // 480 s of ramp
        for u in [1.0, 60.0, 240.0, 479.0] {
            let st = ch.state(100.0 + u);
            assert!((st.setpoint_c - (20.0 + s * u)).abs() < 1e-12);
            assert!(st.ramping && !st.saturated);
            // Air = ramp through the lag: trails by s·τ·(1 − e^{−u/τ}).
            let want = 20.0 + s * u - s * tau * (1.0 - (-u / tau).exp());
            assert!((st.air_c - want).abs() < 1e-11, "u={u}: {} vs {want}", st.air_c);
            assert!((st.air_rate_c_s - s * (1.0 - (-u / tau).exp())).abs() < 1e-14);
        }
        // After the set point arrives, the air closes the gap exponentially.
        let gap0 = s * tau * (1.0 - (-(t_reach - 100.0) / tau).exp());
        for v in [0.0, 10.0, 500.0] {
            let st = ch.state(t_reach + v);
            assert!(!st.ramping && st.setpoint_c == 60.0);
            assert!((st.air_c - (60.0 - gap0 * (-v / tau).exp())).abs() < 1e-10);
        }
        // Cooling is limited to 3.5 °C/min.
        let used = ch.set_target(3000.0, -40.0, None).expect("accepted");
        assert_eq!(used, 3.5 / 60.0);
        assert!((ch.state(3060.0).setpoint_rate_c_s + 3.5 / 60.0).abs() < 1e-15);
    }

    #[test]
    fn air_slew_limit_binds_from_the_closed_form_crossing_time() {
        let h = 1.0 / 60.0;
        let p = ChamberParams { air_heat_slew_c_s: h, ..quiet() };
        let mut ch = ChamberModel::new(p, 20.0, 0.0);
        let s = 5.0 / 60.0;
        ch.set_target(0.0, 80.0, None).expect("accepted");
        let tau = 120.0;
        let u_cross = -tau * (1.0 - h / s).ln();
        let before = ch.state(u_cross - 1e-3);
        assert!(!before.saturated && before.air_rate_c_s < h);
        let after = ch.state(u_cross + 10.0);
        assert!(after.saturated && (after.air_rate_c_s - h).abs() < 1e-15);
        let a_cross = 20.0 + s * u_cross - s * tau * (1.0 - (-u_cross / tau).exp());
        assert!((after.air_c - (a_cross + 10.0 * h)).abs() < 1e-9);
        // Slew limited until the gap to the set point (held at 80 from 720 s) falls to h·τ.
        let t_sp = 60.0 / s;
        let t_free = u_cross + (80.0 - a_cross - h * tau) / h;
        assert!(t_free > t_sp);
        assert!(ch.state(t_free - 1.0).saturated);
        let st = ch.state(t_free + 1.0);
        assert!(!st.saturated && st.air_rate_c_s < h);
        // The air is continuous across the breakpoints.
        let mut prev = ch.state(0.0).air_c;
        let mut t = 0.0;
        while t < 3000.0 {
            t += 0.25;
            let a = ch.state(t).air_c;
            assert!((a - prev).abs() <= h * 0.25 * (1.0 + 1e-9) + 1e-12, "jump at {t}");
            prev = a;
        }
    }

    fn rk4_cascade(
        p: &ChamberParams,
        tau_g: f64,
        sp: impl Fn(f64) -> f64,
        t_end: f64,
        a0: f64,
    ) -> (f64, f64) {
        let ta = p.air_time_constant_s;
        let f = |t: f64, a: f64, g: f64| ((sp(t) - a) / ta, (a - g) / tau_g);
        let (mut a, mut g) = (a0, a0);
        let h = 0.01;
        let steps = (t_end / h).round() as usize;
        for i in 0..steps {
            // Step boundaries on whole multiples of h, so the set point's kink falls on one.
            let t = i as f64 * h;
            let (k1a, k1g) = f(t, a, g);
            let (k2a, k2g) = f(t + h / 2.0, a + h / 2.0 * k1a, g + h / 2.0 * k1g);
            let (k3a, k3g) = f(t + h / 2.0, a + h / 2.0 * k2a, g + h / 2.0 * k2g);
            let (k4a, k4g) = f(t + h, a + h * k3a, g + h * k3g);
            a += h / 6.0 * (k1a + 2.0 * k2a + 2.0 * k3a + k4a);
            g += h / 6.0 * (k1g + 2.0 * k2g + 2.0 * k3g + k4g);
        }
        (a, g)
    }

    #[test]
    fn payload_follows_air_through_its_lag_exactly() {
        for tau_g in [300.0, 120.0, 120.00001, 30.0] {
            let mut ch = ChamberModel::new(quiet(), 20.0, tau_g);
            ch.set_target(0.0, 40.0, Some(2.0 / 60.0)).expect("accepted");
            let s = 2.0 / 60.0;
            let sp = |t: f64| (20.0 + s * t).min(40.0);
            for t_end in [100.0, 600.0, 1500.0] {
                let (a, g) = rk4_cascade(ch.params(), tau_g, sp, t_end, 20.0);
                let st = ch.state(t_end);
                assert!(
                    (st.air_c - a).abs() < 1e-8,
                    "τg={tau_g} t={t_end}: air {} vs {a}",
                    st.air_c
                );
                assert!(
                    (st.payload_c - g).abs() < 1e-8,
                    "τg={tau_g} t={t_end}: {} vs {g}",
                    st.payload_c
                );
                assert!((st.payload_rate_c_s - (st.air_c - st.payload_c) / tau_g).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn state_does_not_depend_on_when_it_is_evaluated() {
        let mut a = ChamberModel::new(ChamberParams::default(), 20.0, 300.0);
        let mut b = a.clone();
        for m in [&mut a, &mut b] {
            m.set_target(10.0, 60.0, None).expect("ok");
        }
        for k in 0..20_000 {
            a.state(10.0 + 0.05 * k as f64);
        }
        let t = 10.0 + 0.05 * 20_000.0;
        for m in [&mut a, &mut b] {
            m.set_target(t, -40.0, Some(0.01)).expect("ok");
        }
        assert_eq!(a.state(5000.0), b.state(5000.0));
    }

    #[test]
    fn bad_targets_and_ramps_are_errors() {
        let mut ch = ChamberModel::new(ChamberParams::default(), 20.0, 0.0);
        assert!(matches!(
            ch.set_target(0.0, 200.0, None),
            Err(ChamberError::TargetOutOfRange { .. })
        ));
        assert!(matches!(
            ch.set_target(0.0, -60.0, None),
            Err(ChamberError::TargetOutOfRange { .. })
        ));
        assert!(matches!(
            ch.set_target(0.0, f64::NAN, None),
            Err(ChamberError::TargetOutOfRange { .. })
        ));
        assert!(matches!(ch.set_target(0.0, 30.0, Some(0.0)), Err(ChamberError::BadRamp { .. })));
        assert!(matches!(
            ch.set_target(0.0, 30.0, Some(f64::INFINITY)),
            Err(ChamberError::BadRamp { .. })
        ));
        ch.set_target(10.0, 30.0, None).expect("ok");
        assert!(matches!(ch.set_target(5.0, 30.0, None), Err(ChamberError::TimeReversed { .. })));
    }

    #[test]
    fn readout_is_quantised_to_the_resolution() {
        let mut ch = ChamberModel::new(ChamberParams::default(), 20.0, 0.0);
        ch.set_target(0.0, 23.0, None).expect("ok");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for k in 0..100 {
            let st = ch.state(k as f64 * 0.37);
            let r = ch.readout(&st, &mut rng);
            let q = r.temperature_c / 0.1;
            assert!((q - q.round()).abs() < 1e-9);
            assert!((r.temperature_c - st.air_c).abs() < 0.05 + 5.0 * 0.01);
        }
    }
}
