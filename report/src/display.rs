//! The units bench shows people: engineering units for display (°/h, ppm, °/h/°C,
//! °/h/(°C/min)), SI in files. One table, used by the terminal, the JSON's display fields and
//! the reports.

use bench_physics::units::{ARCSEC, DEG, DEG_PER_H, DEG_PER_SQRT_H};
use bench_physics::ModelKey;

/// A display unit: its name and how many of it make one SI unit of the quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    /// Name, e.g. `°/h`.
    pub name: &'static str,
    /// Display value per SI value.
    pub per_si: f64,
}

impl Unit {
    /// `si` in this unit.
    pub fn of(self, si: f64) -> f64 {
        si * self.per_si
    }
}

/// Angular rate: °/h.
pub const RATE: Unit = Unit { name: "°/h", per_si: 1.0 / DEG_PER_H };
/// Dimensionless scale-factor error: ppm.
pub const PPM: Unit = Unit { name: "ppm", per_si: 1e6 };
/// Bias per temperature: °/h per °C.
pub const TEMP_COEFF: Unit = Unit { name: "°/h/°C", per_si: 1.0 / DEG_PER_H };
/// Bias per temperature rate: °/h per (°C/min) — one °C/min is 1/60 °C/s.
pub const TEMP_RATE_COEFF: Unit = Unit { name: "°/h/(°C/min)", per_si: 1.0 / (60.0 * DEG_PER_H) };

/// Angle random walk: °/√h.
pub const ARW: Unit = Unit { name: "°/√h", per_si: 1.0 / DEG_PER_SQRT_H };
/// Angle: degrees.
pub const DEGREES: Unit = Unit { name: "°", per_si: 1.0 / DEG };
/// Small angle: arc seconds.
pub const ARC_SECONDS: Unit = Unit { name: "″", per_si: 1.0 / ARCSEC };
/// Angular rate of the table: °/min.
pub const TABLE_RATE: Unit = Unit { name: "°/min", per_si: 60.0 / DEG };
/// Angular rate in degrees per second.
pub const DEG_PER_S: Unit = Unit { name: "°/s", per_si: 1.0 / DEG };
/// Temperature rate: °C/min.
pub const TEMP_RATE: Unit = Unit { name: "°C/min", per_si: 60.0 };
/// Time: s.
pub const SECONDS: Unit = Unit { name: "s", per_si: 1.0 };
/// Short time: ms.
pub const MILLISECONDS: Unit = Unit { name: "ms", per_si: 1e3 };
/// Time: minutes.
pub const MINUTES: Unit = Unit { name: "min", per_si: 1.0 / 60.0 };
/// Time: hours (time axes of the figures).
pub const HOURS: Unit = Unit { name: "h", per_si: 1.0 / 3600.0 };
/// Temperature: °C.
pub const CELSIUS: Unit = Unit { name: "°C", per_si: 1.0 };
/// A pure number shown as it is (a count, a gain, a flag).
pub const ONE: Unit = Unit { name: "", per_si: 1.0 };

/// The display unit of a calibrated coefficient (`None` for the model's other keys).
pub fn coefficient_unit(key: ModelKey) -> Option<Unit> {
    match key {
        ModelKey::Bias => Some(RATE),
        ModelKey::ScaleFactorError => Some(PPM),
        ModelKey::TempCoeff => Some(TEMP_COEFF),
        ModelKey::TempRateCoeff => Some(TEMP_RATE_COEFF),
        _ => None,
    }
}

/// The display unit of any key of the gyro model.
pub fn model_key_unit(key: ModelKey) -> Unit {
    coefficient_unit(key).unwrap_or(match key {
        ModelKey::ReferenceTemperature => CELSIUS,
        ModelKey::Arw => ARW,
        ModelKey::BiasInstability => RATE,
        ModelKey::ThermalTimeConstant => SECONDS,
        _ => ONE,
    })
}

/// The display unit of a quantity the analysis names by its SI unit (an effect's parameter:
/// `rad/s`, `rad/s²`, `rad`, `deg`, `s`, `1/°C`, `rad/s/°C²`, `s/rad`, `1`); an unknown unit
/// is shown as it is.
pub fn for_si(si: &'static str) -> Unit {
    match si {
        "rad/s" => RATE,
        "rad/s/°C" => TEMP_COEFF,
        "rad/s/(°C/s)" => TEMP_RATE_COEFF,
        "rad/s/°C²" => Unit { name: "°/h/°C²", per_si: 1.0 / DEG_PER_H },
        // A rate's trend in time: °/h per hour.
        "rad/s²" => Unit { name: "°/h/h", per_si: 3600.0 / DEG_PER_H },
        "1/°C" => Unit { name: "ppm/°C", per_si: 1e6 },
        // A relative error per rate: ppm per °/s.
        "s/rad" => Unit { name: "ppm/(°/s)", per_si: 1e6 * DEG },
        "rad" => DEGREES,
        "deg" => Unit { name: "°", per_si: 1.0 },
        "rad/√s" => ARW,
        "s" => SECONDS,
        "°C" => CELSIUS,
        "1" => ONE,
        other => Unit { name: other, per_si: 1.0 },
    }
}

/// An effect parameter's name for display, without the SI unit its key carries
/// (`amplitude_rad_s` → `amplitude`, `time_constant_s` → `time constant`): the value beside it
/// is in display units.
pub fn parameter_name(key: &str) -> String {
    const SUFFIXES: [&str; 8] =
        ["_rad_s_per_c2", "_s_per_rad", "_per_c", "_rad_s2", "_rad_s", "_rad", "_deg", "_s"];
    let bare = SUFFIXES.iter().find_map(|s| key.strip_suffix(s)).unwrap_or(key);
    bare.replace('_', " ")
}

/// `x` to `digits` significant digits (plain between 1e-3 and 1e5, else `1.23e-5`), `n/a`
/// when not finite: a number with no σ to set its digits.
pub fn sig(x: f64, digits: usize) -> String {
    crate::render::sig(x, digits)
}

/// Decimals that show `sigma` to two significant digits (`None` when σ is not a positive
/// finite number, or too small or large for plain decimals).
fn sigma_decimals(sigma: f64) -> Option<usize> {
    if !(sigma.is_finite() && sigma > 0.0) {
        return None;
    }
    // σ rounded to two digits first (0.0996 → 0.10), so the exponent is the rounded one's.
    let e: i32 = format!("{sigma:.1e}").split_once('e')?.1.parse().ok()?;
    let decimals = 1 - e;
    (-6..=12).contains(&decimals).then_some(decimals.max(0) as usize)
}

/// `value ± σ` in display units (both already converted) with the unit: σ to two significant
/// digits and the value to the same decimal place (`12.346 ± 0.021 °/h`); when σ is missing,
/// zero or not finite, the value to 4 significant digits and `± n/a` for a non-finite σ.
pub fn value_sigma(value: f64, sigma: f64, unit: &str) -> String {
    let body = match sigma_decimals(sigma) {
        Some(d) => format!("{value:.d$} ± {sigma:.d$}"),
        None if sigma.is_finite() && sigma > 0.0 => {
            format!("{} ± {}", sig(value, 4), sig(sigma, 2))
        }
        None if sigma.is_nan() || sigma.is_infinite() => format!("{} ± n/a", sig(value, 4)),
        None => sig(value, 4),
    };
    with_unit(body, unit)
}

/// A value with no σ in display units, to the decimals `sigma` sets when there is one (so it
/// lines up with a `value ± σ` beside it), else 4 significant digits; with the unit.
pub fn value_like(value: f64, sigma: f64, unit: &str) -> String {
    let body = match sigma_decimals(sigma) {
        Some(d) => format!("{value:.d$}"),
        None => sig(value, 4),
    };
    with_unit(body, unit)
}

/// An SI `value ± σ` shown in `unit`.
pub fn si_value_sigma(unit: Unit, value_si: f64, sigma_si: f64) -> String {
    value_sigma(unit.of(value_si), unit.of(sigma_si), unit.name)
}

/// An SI value shown in `unit` to `digits` significant digits.
pub fn si_value(unit: Unit, value_si: f64, digits: usize) -> String {
    with_unit(sig(unit.of(value_si), digits), unit.name)
}

/// Seconds as `h:mm:ss`, rounded to the nearest second (59.6 s is `0:01:00`: a time shown to
/// the second is the second nearest to it); a negative or non-finite time is `0:00:00`. The
/// one time formatter of the terminal and the reports.
pub fn hms(t_s: f64) -> String {
    let s = if t_s.is_finite() && t_s > 0.0 { t_s.round() as u64 } else { 0 };
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

fn with_unit(body: String, unit: &str) -> String {
    if unit.is_empty() {
        body
    } else {
        format!("{body} {unit}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficients_convert_to_engineering_units() {
        let close = |a: f64, b: f64| (a / b - 1.0).abs() < 1e-12;
        assert!(close(RATE.of(DEG_PER_H), 1.0));
        assert!(close(PPM.of(5e-5), 50.0));
        // 1 °/h per °C/s is 1/60 °/h per °C/min.
        assert!(close(TEMP_RATE_COEFF.of(DEG_PER_H), 1.0 / 60.0));
        for k in ModelKey::CALIBRATED {
            assert!(coefficient_unit(k).is_some(), "{}", k.key());
        }
        assert_eq!(coefficient_unit(ModelKey::Arw), None);
    }

    #[test]
    fn hms_rounds_to_the_nearest_second() {
        assert_eq!(hms(0.0), "0:00:00");
        assert_eq!(hms(0.49), "0:00:00");
        assert_eq!(hms(59.5), "0:01:00");
        assert_eq!(hms(3599.6), "1:00:00");
        assert_eq!(hms(4699.75), "1:18:20");
        assert_eq!(hms(36_000.0 + 61.2), "10:01:01");
        assert_eq!(hms(-3.0), "0:00:00");
        assert_eq!(hms(f64::NAN), "0:00:00");
        assert_eq!(hms(f64::INFINITY), "0:00:00");
    }

    #[test]
    fn sigma_sets_the_digits() {
        assert_eq!(value_sigma(12.34567, 0.02134, "°/h"), "12.346 ± 0.021 °/h");
        assert_eq!(value_sigma(2998.2, 5.0, "s"), "2998.2 ± 5.0 s");
        assert_eq!(value_sigma(601.0, 63.0, "s"), "601 ± 63 s");
        assert_eq!(value_sigma(0.5, 0.0996, "°"), "0.50 ± 0.10 °");
        assert_eq!(value_sigma(1.5, f64::INFINITY, "ppm"), "1.500 ± n/a ppm");
        assert_eq!(value_like(3.0, 0.021, "°/h"), "3.000 °/h");
        assert_eq!(value_sigma(0.3, 0.02, ""), "0.300 ± 0.020");
        // 7.1e-8 ± 1.7e-8 rad/s is 0.0146 ± 0.0035 °/h.
        assert_eq!(si_value_sigma(for_si("rad/s"), 7.1e-8, 1.7e-8), "0.0146 ± 0.0035 °/h");
        assert_eq!(si_value_sigma(for_si("rad"), 0.78, 0.2), "45 ± 11 °");
        assert_eq!(parameter_name("amplitude_rad_s"), "amplitude");
        assert_eq!(parameter_name("time_constant_s"), "time constant");
        assert_eq!(parameter_name("coeff_per_c"), "coeff");
        assert_eq!(parameter_name("gain"), "gain");
        assert_eq!(parameter_name("slope_rad_s2"), "slope");
        // 1 °/h per hour.
        assert!((for_si("rad/s²").of(DEG_PER_H / 3600.0) - 1.0).abs() < 1e-12);
    }
}
