//! Single-axis rate-table dynamics: an acceleration-limited rate loop, rate ripple at N cycles
//! per revolution, and the position and rate readouts.
//!
//! The commanded motion is a chain of segments, each a constant-acceleration slew to the
//! commanded rate followed by constant rate, so the *nominal* angle `θ_n(t)` and rate `ω_n(t)`
//! are exact closed forms at any time. Rate ripple of relative amplitude `ε` at `N` cycles per
//! revolution and phase `φ`, `ω = ω_n·(1 + ε·sin(N·θ_n + φ))`, integrates exactly to
//! `θ = θ_n + (ε/N)·(cos φ − cos(N·θ_n + φ))` for any motion profile. Evaluating the state is a pure
//! function of time and of the commands given so far, so the result does not depend on when
//! or how often it is asked for. Angles are unwrapped, positive counter-clockwise seen from
//! above.

use rand::Rng;
use rand_distr::StandardNormal;

use crate::units::{quantise, ARCSEC, DEG};

/// Rate-table parameters. Defaults: an Actidyn ST1300-class table.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TableParams {
    /// Largest rate magnitude, rad/s (default 1000 °/s).
    pub max_rate_rad_s: f64,
    /// Largest acceleration magnitude, rad/s² (default 1000 °/s²).
    pub max_accel_rad_s2: f64,
    /// Position readout resolution, rad (default 1″ = 4.8481e-6 rad).
    pub position_resolution_rad: f64,
    /// Relative amplitude ε of the rate ripple (default 1e-5).
    pub ripple_rel: f64,
    /// Ripple cycles per revolution N (default 16, e.g. torque-motor cogging; 0 = no ripple).
    /// The ripple's angle excursion is `2ε/N` peak to peak (default 1.25e-6 rad ≈ 0.26″).
    pub ripple_cycles_per_rev: u32,
    /// Phase φ of the ripple, `ω = ω_n·(1 + ε·sin(N·θ_n + φ))`, rad (default 0).
    pub ripple_phase_rad: f64,
    /// Standard deviation of the measured-rate readout noise, rad/s (default 1e-6 ≈ 0.2 °/h).
    pub rate_noise_rad_s: f64,
}

impl Default for TableParams {
    fn default() -> Self {
        Self {
            max_rate_rad_s: 1000.0 * DEG,
            max_accel_rad_s2: 1000.0 * DEG,
            position_resolution_rad: ARCSEC,
            ripple_rel: 1e-5,
            ripple_cycles_per_rev: 16,
            ripple_phase_rad: 0.0,
            rate_noise_rad_s: 1e-6,
        }
    }
}

/// Axis mode of the simulated rate loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AxisMode {
    /// Following a commanded rate.
    Rate,
    /// Decelerating to rest, or held at rest.
    Stopped,
}

/// A rejected table command.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TableError {
    /// Commanded rate beyond the table's limit (or not finite).
    #[error("rate {rate_rad_s} rad/s is outside ±{max_rad_s} rad/s")]
    RateOutOfRange {
        /// The command.
        rate_rad_s: f64,
        /// The limit.
        max_rad_s: f64,
    },
    /// Acceleration not positive, not finite or beyond the table's limit.
    #[error("acceleration {accel_rad_s2} rad/s² is outside (0, {max_rad_s2}] rad/s²")]
    AccelOutOfRange {
        /// The command.
        accel_rad_s2: f64,
        /// The limit.
        max_rad_s2: f64,
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

/// At rest at angle 0, time 0.
const REST: Segment = Segment {
    t0: 0.0,
    theta0: 0.0,
    omega0: 0.0,
    accel: 0.0,
    slew_s: 0.0,
    omega_cmd: 0.0,
    mode: AxisMode::Stopped,
};

#[derive(Debug, Clone, Copy)]
struct Segment {
    t0: f64,
    theta0: f64,
    omega0: f64,
    accel: f64,
    slew_s: f64,
    omega_cmd: f64,
    mode: AxisMode,
}

impl Segment {
    /// Nominal angle and rate `u` seconds into the segment.
    #[inline]
    fn nominal(&self, u: f64) -> (f64, f64) {
        let u = u.max(0.0);
        if u < self.slew_s {
            (self.theta0 + u * (self.omega0 + 0.5 * self.accel * u), self.omega0 + self.accel * u)
        } else {
            let ua = self.slew_s;
            let th = self.theta0
                + ua * (self.omega0 + 0.5 * self.accel * ua)
                + self.omega_cmd * (u - ua);
            (th, self.omega_cmd)
        }
    }
}

/// True state of the table at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableState {
    /// Time, s.
    pub time_s: f64,
    /// True angle, rad, unwrapped.
    pub angle_rad: f64,
    /// True rate, rad/s.
    pub rate_rad_s: f64,
    /// Commanded rate, rad/s.
    pub rate_command_rad_s: f64,
    /// Axis mode.
    pub mode: AxisMode,
    /// Still accelerating toward the command.
    pub slewing: bool,
}

/// What the controller reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableReadout {
    /// Angle quantised to the position resolution, rad.
    pub angle_rad: f64,
    /// Measured rate (true rate plus readout noise), rad/s.
    pub rate_rad_s: f64,
}

/// The rate table: commands in, exact true state out at any time.
#[derive(Debug, Clone)]
pub struct RateTableModel {
    params: TableParams,
    segments: Vec<Segment>,
}

/// Segments kept for looking back in time; older ones are dropped.
const KEEP_SEGMENTS: usize = 256;

impl RateTableModel {
    /// A table at rest at angle 0 at time 0.
    pub fn new(params: TableParams) -> Self {
        Self { params, segments: vec![REST] }
    }

    /// The parameters.
    pub fn params(&self) -> &TableParams {
        &self.params
    }

    fn segment_at(&self, t_s: f64) -> &Segment {
        self.segments.iter().rev().find(|s| s.t0 <= t_s).or(self.segments.first()).unwrap_or(&REST)
    }

    /// Command rate mode: slew to `rate_rad_s` at acceleration magnitude `accel_rad_s2`,
    /// starting at time `t_s` (s), which must not be before the previous command.
    pub fn command_rate(
        &mut self,
        t_s: f64,
        rate_rad_s: f64,
        accel_rad_s2: f64,
    ) -> Result<(), TableError> {
        let max = self.params.max_rate_rad_s;
        if !rate_rad_s.is_finite() || rate_rad_s.abs() > max * (1.0 + 1e-12) {
            return Err(TableError::RateOutOfRange { rate_rad_s, max_rad_s: max });
        }
        self.start_segment(t_s, rate_rad_s.clamp(-max, max), accel_rad_s2, AxisMode::Rate)
    }

    /// Decelerate to rest at `decel_rad_s2` from time `t_s` and hold.
    pub fn stop(&mut self, t_s: f64, decel_rad_s2: f64) -> Result<(), TableError> {
        self.start_segment(t_s, 0.0, decel_rad_s2, AxisMode::Stopped)
    }

    fn start_segment(
        &mut self,
        t_s: f64,
        omega_cmd: f64,
        accel: f64,
        mode: AxisMode,
    ) -> Result<(), TableError> {
        let amax = self.params.max_accel_rad_s2;
        if !(accel.is_finite() && accel > 0.0 && accel <= amax * (1.0 + 1e-12)) {
            return Err(TableError::AccelOutOfRange { accel_rad_s2: accel, max_rad_s2: amax });
        }
        let last = self.segments.last().copied().unwrap_or(REST);
        if !t_s.is_finite() || t_s < last.t0 {
            return Err(TableError::TimeReversed { t_s, previous_s: last.t0 });
        }
        let (theta0, omega0) = last.nominal(t_s - last.t0);
        let dv = omega_cmd - omega0;
        let a = accel.min(amax);
        let seg = Segment {
            t0: t_s,
            theta0,
            omega0,
            accel: a.copysign(dv),
            slew_s: dv.abs() / a,
            omega_cmd,
            mode,
        };
        if self.segments.len() >= KEEP_SEGMENTS {
            self.segments.drain(..KEEP_SEGMENTS / 2);
        }
        self.segments.push(seg);
        Ok(())
    }

    /// True angle at `t_s`, rad (nominal angle plus the ripple's angle).
    #[inline]
    pub fn true_angle(&self, t_s: f64) -> f64 {
        let seg = self.segment_at(t_s);
        let (th, _) = seg.nominal(t_s - seg.t0);
        th + self.ripple_angle(th)
    }

    #[inline]
    fn ripple_angle(&self, theta_nominal: f64) -> f64 {
        let n = self.params.ripple_cycles_per_rev;
        if n == 0 || self.params.ripple_rel == 0.0 {
            return 0.0;
        }
        let n = f64::from(n);
        let phi = self.params.ripple_phase_rad;
        self.params.ripple_rel / n * (phi.cos() - (n * theta_nominal + phi).cos())
    }

    /// True state at `t_s`.
    pub fn state(&self, t_s: f64) -> TableState {
        let seg = self.segment_at(t_s);
        let u = t_s - seg.t0;
        let (th, om) = seg.nominal(u);
        let n = self.params.ripple_cycles_per_rev;
        let (angle, rate) = if n == 0 || self.params.ripple_rel == 0.0 {
            (th, om)
        } else {
            let nf = f64::from(n);
            let phi = self.params.ripple_phase_rad;
            let (s, c) = (nf * th + phi).sin_cos();
            let eps = self.params.ripple_rel;
            (th + eps / nf * (phi.cos() - c), om * (1.0 + eps * s))
        };
        TableState {
            time_s: t_s,
            angle_rad: angle,
            rate_rad_s: rate,
            rate_command_rad_s: seg.omega_cmd,
            mode: seg.mode,
            slewing: u < seg.slew_s,
        }
    }

    /// Readout of `state`: angle quantised to the position resolution, rate plus readout noise
    /// drawn from `rng`.
    pub fn readout<R: Rng + ?Sized>(&self, state: &TableState, rng: &mut R) -> TableReadout {
        let mut rate = state.rate_rad_s;
        if self.params.rate_noise_rad_s > 0.0 {
            let n: f64 = rng.sample(StandardNormal);
            rate += self.params.rate_noise_rad_s * n;
        }
        TableReadout {
            angle_rad: quantise(state.angle_rad, self.params.position_resolution_rad),
            rate_rad_s: rate,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::DEG_PER_MIN;
    use rand::SeedableRng;

    fn no_ripple() -> TableParams {
        TableParams { ripple_rel: 0.0, ..TableParams::default() }
    }

    #[test]
    fn slew_takes_v_over_a_and_covers_v2_over_2a() {
        let (v, a) = (100.0 * DEG, 20.0 * DEG);
        let mut t = RateTableModel::new(no_ripple());
        t.command_rate(2.0, v, a).expect("accepted");
        let t_slew = v / a; // 5 s
        let s = t.state(2.0 + 0.5 * t_slew);
        assert!(s.slewing && (s.rate_rad_s - 0.5 * v).abs() < 1e-12);
        let s = t.state(2.0 + t_slew - 1e-6);
        assert!(s.slewing);
        let s = t.state(2.0 + t_slew + 1e-6);
        assert!(!s.slewing && (s.rate_rad_s - v).abs() < 1e-12);
        // Angle at the end of the slew: v²/2a; then grows at v.
        let th = t.true_angle(2.0 + t_slew);
        assert!((th - v * v / (2.0 * a)).abs() < 1e-12);
        let th = t.true_angle(2.0 + t_slew + 10.0);
        assert!((th - (v * v / (2.0 * a) + 10.0 * v)).abs() < 1e-11);
        // Stop from v at 2a: takes v/2a, covers v²/4a more.
        let t_stop = 2.0 + t_slew + 10.0;
        t.stop(t_stop, 2.0 * a).expect("accepted");
        let end = t.state(t_stop + v / (2.0 * a) + 1.0);
        assert_eq!(end.mode, AxisMode::Stopped);
        assert!(end.rate_rad_s.abs() < 1e-15 && !end.slewing);
        assert!((end.angle_rad - (v * v / (2.0 * a) + 10.0 * v + v * v / (4.0 * a))).abs() < 1e-11);
    }

    #[test]
    fn reversal_passes_through_zero_with_constant_acceleration() {
        let w = 10.0 * DEG_PER_MIN;
        let mut t = RateTableModel::new(no_ripple());
        t.command_rate(0.0, w, 1.0).expect("ok");
        t.command_rate(100.0, -w, 1e-3).expect("ok");
        let s = t.state(100.0 + w / 1e-3);
        assert!(s.rate_rad_s.abs() < 1e-15 && s.slewing);
        assert!((t.state(100.0 + 2.0 * w / 1e-3 + 1.0).rate_rad_s + w).abs() < 1e-15);
    }

    #[test]
    fn angle_readout_is_quantised_to_one_arcsec_and_unwrapped() {
        let w = 10.0 * DEG;
        let mut t = RateTableModel::new(no_ripple());
        t.command_rate(0.0, w, 1000.0 * DEG).expect("ok");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for k in 1..200 {
            let time = 0.731 * k as f64;
            let s = t.state(time);
            let r = t.readout(&s, &mut rng);
            let steps = r.angle_rad / ARCSEC;
            assert!((steps - steps.round()).abs() < 1e-6, "not a multiple of 1″");
            assert!((r.angle_rad - s.angle_rad).abs() <= 0.5 * ARCSEC * (1.0 + 1e-9));
        }
        // 139 s at 10 °/s is 1390°: unwrapped, not folded into 0..360.
        assert!(t.true_angle(139.0) > 1380.0 * DEG);
    }

    #[test]
    fn ripple_integrates_exactly_and_averages_out_per_revolution() {
        let p = TableParams {
            ripple_rel: 1e-3,
            ripple_cycles_per_rev: 4,
            ripple_phase_rad: 0.7,
            ..TableParams::default()
        };
        let w = 90.0 * DEG;
        let mut t = RateTableModel::new(p);
        t.command_rate(0.0, w, 1e6 * DEG / 1e3).expect("ok");
        let t0 = 10.0;
        // Integrate the ripple rate numerically (Simpson) and compare with the closed form.
        let n = 20_000;
        let h = 3.0 / n as f64;
        let mut integral = 0.0;
        for i in 0..=n {
            let wgt = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            integral += wgt * t.state(t0 + i as f64 * h).rate_rad_s;
        }
        integral *= h / 3.0;
        let d = t.true_angle(t0 + 3.0) - t.true_angle(t0);
        assert!((d - integral).abs() < 1e-10, "{d} vs {integral}");
        // One full revolution at constant rate: the ripple cancels.
        let rev = 2.0 * std::f64::consts::PI / w;
        assert!(
            (t.true_angle(t0 + rev) - t.true_angle(t0) - 2.0 * std::f64::consts::PI).abs() < 1e-12
        );
        assert!(((t.true_angle(t0 + rev / 8.0) - t.true_angle(t0)) - w * rev / 8.0).abs() > 1e-5);
    }

    #[test]
    fn bad_commands_are_rejected() {
        let mut t = RateTableModel::new(TableParams::default());
        assert!(matches!(
            t.command_rate(0.0, 2000.0 * DEG, 1.0),
            Err(TableError::RateOutOfRange { .. })
        ));
        assert!(matches!(
            t.command_rate(0.0, f64::NAN, 1.0),
            Err(TableError::RateOutOfRange { .. })
        ));
        assert!(matches!(t.command_rate(0.0, 1.0, 0.0), Err(TableError::AccelOutOfRange { .. })));
        assert!(matches!(
            t.command_rate(0.0, 1.0, 5000.0 * DEG),
            Err(TableError::AccelOutOfRange { .. })
        ));
        t.command_rate(5.0, 1.0, 1.0).expect("ok");
        assert!(matches!(t.stop(4.0, 1.0), Err(TableError::TimeReversed { .. })));
    }
}
