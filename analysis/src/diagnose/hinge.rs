//! A kink in k_t, physics outside the library: the hinge members of the temperature family.
//!
//! A bias `c·max(0, T − T_k)` (k_t changes by `c` at `T_k`) is half a V in temperature beyond
//! the line k_t already fits, and `(T − T0)²` takes most of a half-V (over a span centred on
//! the knot their residuals after a line correlate at ρ ≈ 0.97). Without a kinked member the
//! quadratic's family check cannot see that the shape is wrong, and the quadratic is named for
//! physics that is not in the library. So the temperature family holds the hinges
//! `max(0, T − T_k)` at knots on a grid of the recording's own temperatures (its deciles, the
//! knots nearer than 2 % of the span merged), tested as one member whose look-elsewhere over
//! the knots is counted in its threshold ([`super::family::Member::looks`]). With a
//! temperature effect in the model:
//! - a hinge significant beside it: the effect is not named, and the structure is reported
//!   unexplained, "k_t changes near T_k";
//! - a hinge that explains the data alone (its Wald over its threshold, which carries the
//!   knots' look-elsewhere) while the effect beside it does not stay significant: the two are
//!   not told apart, and the effect is not named (which of the two explains more is a guess
//!   where neither holds beside the other);
//! - otherwise the effect is named: a true quadratic leaves no hinge in its residual, and keeps
//!   its significance beside its best hinge where it is strong enough to be told from one.
//!
//! On a gyro without its own sensor the hinges above are built at the lag in use. A coil that
//! lags far more than the lab's model says moves the kink's passage in time, and at the lag in
//! use it reads as an effect of time (a bias step). So every accepted effect is also judged
//! against the kink with the coil's lag refitted beside it ([`super::coil_lag::kink_rival`],
//! in [`super::nuisance`]): where the kink explains the residual there and the effect keeps
//! nothing beside it, the effect is not named and the kink is reported.

use super::family::Member;
use super::series::bin_mean;
use super::Prepared;

/// The quantiles of the recording's temperatures tried as knots.
const KNOT_QUANTILES: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];

/// Knots nearer than this share of the temperature span are one.
const MERGE_SHARE: f64 = 0.02;

/// Least temperature span (°C) over which a kink can be told from a line.
const MIN_SPAN_C: f64 = 1.0;

/// The knots: the deciles of the bins' mean model temperature, merged where nearer than 2 % of
/// the span; none on a span below [`MIN_SPAN_C`].
pub(super) fn knots(prep: &Prepared) -> Vec<f64> {
    let mut temps = bin_mean(&prep.bins, &prep.native.dt, |k| prep.temp[k]);
    temps.retain(|t| t.is_finite());
    temps.sort_by(f64::total_cmp);
    let (Some(&lo), Some(&hi)) = (temps.first(), temps.last()) else { return Vec::new() };
    if hi - lo < MIN_SPAN_C {
        return Vec::new();
    }
    let mut out: Vec<f64> = Vec::new();
    for q in KNOT_QUANTILES {
        let tk = temps[((temps.len() - 1) as f64 * q).round() as usize];
        if out.last().is_none_or(|&last| tk - last > MERGE_SHARE * (hi - lo)) {
            out.push(tk);
        }
    }
    out
}

/// The hinge `max(0, T − T_k)` at each knot ([`knots`]), as members that share one look-elsewhere.
pub(super) fn members(prep: &Prepared) -> Vec<Member> {
    let knots = knots(prep);
    let looks = knots.len();
    knots
        .into_iter()
        .map(|tk| Member {
            name: format!(
                "k_t changes near {tk:.1} °C (a kink max(0, T − {tk:.1} °C), outside the library)"
            ),
            cols: vec![bin_mean(&prep.bins, &prep.native.dt, |k| (prep.temp[k] - tk).max(0.0))],
            angle_harmonic: false,
            looks,
            kink: true,
        })
        .collect()
}
