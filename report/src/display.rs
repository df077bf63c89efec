//! The units bench shows people: engineering units for display (°/h, ppm, °/h/°C,
//! °/h/(°C/min)), SI in files. One table, used by the terminal, the JSON's display fields and
//! the reports.

use bench_physics::units::DEG_PER_H;
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
}
