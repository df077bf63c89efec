//! First-order lag `τ·dy/dt = u − y`, discretised exactly for an input that is linear over each
//! step (so a ramp passes through it with its closed-form response: after the transient
//! `e^{−t/τ}` dies out, the output trails the input by `rate·τ`).

/// A first-order lag with time constant `tau_s` (s); `tau_s = 0` passes the input through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstOrderLag {
    tau_s: f64,
    y: f64,
}

impl FirstOrderLag {
    /// A lag with time constant `tau_s` (negative or non-finite values are taken as 0) and
    /// initial output `y0`.
    pub fn new(tau_s: f64, y0: f64) -> Self {
        let tau_s = if tau_s.is_finite() && tau_s > 0.0 { tau_s } else { 0.0 };
        Self { tau_s, y: y0 }
    }

    /// Time constant, s.
    pub fn tau_s(&self) -> f64 {
        self.tau_s
    }

    /// Current output.
    pub fn value(&self) -> f64 {
        self.y
    }

    /// Advance by `dt_s` with the input going linearly from `u_start` to `u_end`; returns the
    /// new output. Exact: `y₁ = y₀·e + u₀·(1−e) + s·(dt − τ·(1−e))`, `e = e^{−dt/τ}`,
    /// `s = (u₁ − u₀)/dt`.
    pub fn step_linear(&mut self, u_start: f64, u_end: f64, dt_s: f64) -> f64 {
        self.step_linear_memo(u_start, u_end, dt_s, &mut (f64::NAN, 0.0))
    }

    /// [`Self::step_linear`], with `1 − e^{−dt/τ}` for the last step length kept in `memo`
    /// (`(dt_s, value)`; start from `(NAN, 0)`): the same output bit for bit, one exponential
    /// per change of the step length instead of one per step (a series sampled at a steady
    /// rate has a handful of distinct step lengths).
    pub fn step_linear_memo(
        &mut self,
        u_start: f64,
        u_end: f64,
        dt_s: f64,
        memo: &mut (f64, f64),
    ) -> f64 {
        if self.tau_s == 0.0 {
            self.y = u_end;
        } else if dt_s > 0.0 {
            let s = (u_end - u_start) / dt_s;
            if memo.0.to_bits() != dt_s.to_bits() {
                *memo = (dt_s, -(-dt_s / self.tau_s).exp_m1());
            }
            let one_minus_e = memo.1;
            let e = 1.0 - one_minus_e;
            self.y = self.y * e + u_start * one_minus_e + s * (dt_s - self.tau_s * one_minus_e);
        }
        self.y
    }

    /// Output derivative `dy/dt = (u − y)/τ` for the input value `u` now; for `τ = 0` the
    /// output is the input and its derivative is the input's, `input_rate`.
    pub fn rate(&self, u: f64, input_rate: f64) -> f64 {
        if self.tau_s == 0.0 {
            input_rate
        } else {
            (u - self.y) / self.tau_s
        }
    }
}

/// Closed-form response of a lag starting at rest at 0 to the ramp `u = rate·t`:
/// `y(t) = rate·(t − τ·(1 − e^{−t/τ}))`.
pub fn ramp_response(tau_s: f64, rate: f64, t_s: f64) -> f64 {
    if tau_s <= 0.0 {
        rate * t_s
    } else {
        rate * (t_s + tau_s * (-t_s / tau_s).exp_m1())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The memo changes nothing: over steps of changing and repeating lengths, the memoised
    /// and the plain step give the same output bit for bit.
    #[test]
    fn a_memoised_step_is_the_plain_step_bit_for_bit() {
        let (mut a, mut b) = (FirstOrderLag::new(75.0, 3.0), FirstOrderLag::new(75.0, 3.0));
        let mut memo = (f64::NAN, 0.0);
        let mut u = 3.0;
        for k in 0..500 {
            let dt = [0.05, 0.05, 0.05 + 1e-15, 1.3, 0.05][k % 5];
            let next = 3.0 + (k as f64 * 0.37).sin() * 10.0;
            let (ya, yb) = (a.step_linear(u, next, dt), b.step_linear_memo(u, next, dt, &mut memo));
            assert_eq!(ya.to_bits(), yb.to_bits(), "step {k}");
            u = next;
        }
    }

    #[test]
    fn ramp_through_lag_has_steady_lag_rate_tau_and_exponential_transient() {
        let (tau, rate) = (120.0, 5.0 / 60.0);
        let mut lag = FirstOrderLag::new(tau, 0.0);
        let dt = 0.7;
        let mut t = 0.0f64;
        for _ in 0..2000 {
            let y = lag.step_linear(rate * t, rate * (t + dt), dt);
            t += dt;
            // Transient: the gap to the steady-state trail is rate·τ·e^{−t/τ}.
            let gap = rate * t - y;
            let want = rate * tau * (1.0 - (-t / tau).exp());
            assert!((gap - want).abs() < 1e-12 * (1.0 + t), "t={t} gap={gap} want={want}");
            assert!((lag.rate(rate * t, rate) - rate * (1.0 - (-t / tau).exp())).abs() < 1e-14);
        }
        // Steady state after 1400 s ≈ 11.7 τ: lag = rate·τ = 10 °C.
        assert!(((rate * t - lag.value()) - rate * tau).abs() < 1e-4);
        assert!((lag.value() - ramp_response(tau, rate, t)).abs() < 1e-9);
    }

    #[test]
    fn result_does_not_depend_on_step_size() {
        let mut a = FirstOrderLag::new(10.0, 3.0);
        let mut b = FirstOrderLag::new(10.0, 3.0);
        a.step_linear(0.0, 2.0, 4.0);
        b.step_linear(0.0, 0.5, 1.0);
        b.step_linear(0.5, 2.0, 3.0);
        assert!((a.value() - b.value()).abs() < 1e-14);
        // Step response: y = 3·e^{-0.4} + (ramp response of 0.5·t) at t=4.
        let want = 3.0 * (-0.4f64).exp() + ramp_response(10.0, 0.5, 4.0);
        assert!((a.value() - want).abs() < 1e-14);
    }

    #[test]
    fn zero_tau_passes_through() {
        let mut lag = FirstOrderLag::new(0.0, 1.0);
        assert_eq!(lag.step_linear(1.0, 7.0, 0.1), 7.0);
        assert_eq!(lag.rate(7.0, 60.0), 60.0);
        assert_eq!(FirstOrderLag::new(-3.0, 0.0).tau_s(), 0.0);
    }
}
