//! Earth's rotation as seen by a gyro with a vertical sensing axis.

/// Earth's sidereal rotation rate, rad/s (WGS 84: 7.2921150e-5 rad/s ≈ 15.041 °/h).
pub const EARTH_RATE_RAD_S: f64 = 7.292_115_0e-5;

/// Component of Earth's rotation along a vertical sensing axis, rad/s: `Ω_E·sin(latitude)` for an
/// axis pointing up, its negative for an axis pointing down.
///
/// ```
/// use bench_physics::earth::{vertical_rate_rad_s, EARTH_RATE_RAD_S};
/// assert_eq!(vertical_rate_rad_s(90.0, true), EARTH_RATE_RAD_S);
/// assert_eq!(vertical_rate_rad_s(0.0, true), 0.0);
/// ```
pub fn vertical_rate_rad_s(latitude_deg: f64, axis_up: bool) -> f64 {
    let up = EARTH_RATE_RAD_S * latitude_deg.to_radians().sin();
    if axis_up {
        up
    } else {
        -up
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::DEG_PER_H;

    #[test]
    fn earth_rate_is_15_041_deg_per_hour() {
        assert!((EARTH_RATE_RAD_S / DEG_PER_H - 15.041_07).abs() < 1e-4);
    }

    #[test]
    fn vertical_component_at_30_deg_is_half_and_flips_with_the_axis() {
        let up = vertical_rate_rad_s(30.0, true);
        assert!((up - 0.5 * EARTH_RATE_RAD_S).abs() < 1e-18);
        assert_eq!(vertical_rate_rad_s(30.0, false), -up);
        // St Petersburg, 59.94° N: 15.04107·sin(59.94°) = 15.04107·0.865502 = 13.0181 °/h.
        assert!((vertical_rate_rad_s(59.94, true) / DEG_PER_H - 13.0181).abs() < 2e-4);
        assert!(vertical_rate_rad_s(-45.0, true) < 0.0);
    }
}
