//! Units: SI internally, degrees and hours accepted at the edges.
//!
//! Every quantity inside bench is SI (rad, rad/s, s) except temperatures, which are °C as in the
//! recording contract. This module holds the conversion factors and a parser for the unit strings
//! that scenario files and bench configs accept.

use std::f64::consts::PI;

/// One degree in radians.
pub const DEG: f64 = PI / 180.0;
/// One arc-second in radians (the ST1300 position resolution, 4.8481e-6 rad).
pub const ARCSEC: f64 = DEG / 3600.0;
/// One degree per hour in rad/s.
pub const DEG_PER_H: f64 = DEG / 3600.0;
/// One degree per minute in rad/s.
pub const DEG_PER_MIN: f64 = DEG / 60.0;
/// One degree per √hour (angle random walk) in rad/√s.
pub const DEG_PER_SQRT_H: f64 = DEG / 60.0;

/// Dimension of a quantity a unit string can express.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dimension {
    /// Angular rate (SI: rad/s).
    AngularRate,
    /// Angular acceleration (SI: rad/s²).
    AngularAcceleration,
    /// Temperature rate (SI here: °C/s).
    TemperatureRate,
    /// Time (SI: s).
    Time,
}

impl Dimension {
    /// The unit strings accepted for this dimension, for error messages.
    pub fn accepted(self) -> &'static [&'static str] {
        match self {
            Dimension::AngularRate => {
                &["rad/s", "deg/s", "deg/min", "deg/h", "°/s", "°/min", "°/h"]
            }
            Dimension::AngularAcceleration => {
                &["rad/s2", "deg/s2", "rad/s²", "deg/s²", "°/s²", "°/s2"]
            }
            Dimension::TemperatureRate => &["C/s", "C/min", "C/h", "°C/s", "°C/min", "°C/h"],
            Dimension::Time => &["s", "min", "h", "ms"],
        }
    }
}

/// Factor that converts a value in `unit` to the SI unit of `dim`, or `None` if the unit is not
/// one of [`Dimension::accepted`]. Whitespace is ignored; `deg` and `°` are interchangeable.
///
/// ```
/// use bench_physics::units::{si_factor, Dimension, DEG_PER_MIN};
/// assert_eq!(si_factor("°/min", Dimension::AngularRate), Some(DEG_PER_MIN));
/// assert_eq!(si_factor("furlong/fortnight", Dimension::AngularRate), None);
/// ```
pub fn si_factor(unit: &str, dim: Dimension) -> Option<f64> {
    let u: String = unit
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect::<String>()
        .replace('°', "deg")
        .replace('²', "2");
    let f = match dim {
        Dimension::AngularRate => match u.as_str() {
            "rad/s" => 1.0,
            "deg/s" => DEG,
            "deg/min" => DEG_PER_MIN,
            "deg/h" => DEG_PER_H,
            _ => return None,
        },
        Dimension::AngularAcceleration => match u.as_str() {
            "rad/s2" => 1.0,
            "deg/s2" => DEG,
            _ => return None,
        },
        Dimension::TemperatureRate => match u.as_str() {
            "C/s" | "degC/s" => 1.0,
            "C/min" | "degC/min" => 1.0 / 60.0,
            "C/h" | "degC/h" => 1.0 / 3600.0,
            _ => return None,
        },
        Dimension::Time => match u.as_str() {
            "s" => 1.0,
            "ms" => 1e-3,
            "min" => 60.0,
            "h" => 3600.0,
            _ => return None,
        },
    };
    Some(f)
}

/// `value` rounded to the nearest multiple of `resolution` (a readout's quantisation);
/// `value` unchanged if `resolution` is not positive.
///
/// ```
/// use bench_physics::units::{quantise, ARCSEC};
/// assert_eq!(quantise(0.26, 0.1), 0.30000000000000004);
/// assert_eq!(quantise(1.4 * ARCSEC, ARCSEC), ARCSEC);
/// ```
pub fn quantise(value: f64, resolution: f64) -> f64 {
    if resolution > 0.0 {
        (value / resolution).round() * resolution
    } else {
        value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_table_rate_is_2_9089e_3_rad_s() {
        let r = 10.0 * si_factor("°/min", Dimension::AngularRate).unwrap_or(f64::NAN);
        assert!((r - 2.908_882_086_657_216e-3).abs() < 1e-15);
    }

    #[test]
    fn arcsec_matches_st1300_resolution() {
        assert!((ARCSEC - 4.8481e-6).abs() < 1e-10);
    }

    #[test]
    fn every_accepted_unit_parses() {
        for dim in [
            Dimension::AngularRate,
            Dimension::AngularAcceleration,
            Dimension::TemperatureRate,
            Dimension::Time,
        ] {
            for u in dim.accepted() {
                assert!(si_factor(u, dim).is_some(), "{u} for {dim:?}");
            }
        }
        assert_eq!(si_factor("deg/s", Dimension::Time), None);
    }
}
