//! Quantities written as `"<number> <unit>"` strings, converted to SI (temperatures to °C).

use bench_physics::units::{si_factor, Dimension};

/// What a scenario quantity measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dim {
    /// Angular rate; SI rad/s.
    AngularRate,
    /// Angular acceleration; SI rad/s².
    AngularAccel,
    /// Rate of temperature change; °C/s.
    TempRate,
    /// Time; s.
    Time,
    /// Temperature; °C.
    Temperature,
    /// Temperature difference (a band); °C.
    TempDifference,
    /// Frequency; Hz.
    Frequency,
}

impl Dim {
    /// Unit strings accepted, for messages.
    pub fn accepted(self) -> &'static [&'static str] {
        match self {
            Dim::AngularRate => &["°/s", "°/min", "°/h", "deg/s", "deg/min", "deg/h", "rad/s"],
            Dim::AngularAccel => &["°/s²", "°/s2", "deg/s²", "deg/s2", "rad/s²", "rad/s2"],
            Dim::TempRate => Dimension::TemperatureRate.accepted(),
            Dim::Time => Dimension::Time.accepted(),
            Dim::Temperature => &["°C", "C", "degC"],
            Dim::TempDifference => &["°C", "C", "degC", "K"],
            Dim::Frequency => &["Hz", "kHz"],
        }
    }

    /// Suffix of the key that takes a plain number in the SI unit (e.g. `wait_s`).
    pub fn si_suffix(self) -> &'static str {
        match self {
            Dim::AngularRate => "rad_s",
            Dim::AngularAccel => "rad_s2",
            Dim::TempRate => "c_s",
            Dim::Time => "s",
            Dim::Temperature | Dim::TempDifference => "c",
            Dim::Frequency => "hz",
        }
    }

    /// A typical example, for messages.
    pub fn example(self) -> &'static str {
        match self {
            Dim::AngularRate => "\"10 °/min\"",
            Dim::AngularAccel => "\"10 °/s²\"",
            Dim::TempRate => "\"1 °C/min\"",
            Dim::Time => "\"10 min\"",
            Dim::Temperature => "\"20 °C\"",
            Dim::TempDifference => "\"0.5 °C\"",
            Dim::Frequency => "\"20 Hz\"",
        }
    }

    /// Factor from `unit` to this dimension's SI unit.
    pub fn factor(self, unit: &str) -> Option<f64> {
        let u: String =
            unit.chars().filter(|c| !c.is_whitespace()).collect::<String>().replace('°', "deg");
        match self {
            Dim::AngularRate => si_factor(&u, Dimension::AngularRate),
            Dim::AngularAccel => si_factor(&u, Dimension::AngularAcceleration),
            Dim::TempRate => si_factor(&u, Dimension::TemperatureRate),
            Dim::Time => si_factor(&u, Dimension::Time),
            Dim::Temperature => matches!(u.as_str(), "C" | "degC").then_some(1.0),
            Dim::TempDifference => matches!(u.as_str(), "C" | "degC" | "K").then_some(1.0),
            Dim::Frequency => match u.as_str() {
                "Hz" => Some(1.0),
                "kHz" => Some(1e3),
                _ => None,
            },
        }
    }
}

/// A parsed quantity: its SI value and the unit it was written in.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantity {
    /// Value in the dimension's SI unit.
    pub si: f64,
    /// The unit as written (trimmed), for messages.
    pub unit: String,
    /// SI value of one `unit`.
    pub factor: f64,
}

impl Quantity {
    /// A quantity given as a plain SI number.
    pub fn si(dim: Dim, si: f64) -> Self {
        let unit = match dim {
            Dim::AngularRate => "rad/s",
            Dim::AngularAccel => "rad/s²",
            Dim::TempRate => "°C/s",
            Dim::Time => "s",
            Dim::Temperature | Dim::TempDifference => "°C",
            Dim::Frequency => "Hz",
        };
        Self { si, unit: unit.to_string(), factor: 1.0 }
    }

    /// `si_value` expressed in this quantity's unit, e.g. `1000 °/s`.
    pub fn show(&self, si_value: f64) -> String {
        format!("{} {}", fmt_num(si_value / self.factor), self.unit)
    }

    /// This quantity itself, in its unit.
    pub fn show_self(&self) -> String {
        self.show(self.si)
    }
}

/// Parse `"<number> <unit>"`. The space may be left out (`"20°C"`). Errors say what is allowed.
pub fn parse(text: &str, dim: Dim) -> Result<Quantity, String> {
    let t = text.trim();
    let split = number_prefix_len(t);
    let (num, unit) = t.split_at(split);
    let unit = unit.trim();
    let allowed = dim.accepted().join(", ");
    if num.is_empty() {
        return Err(format!("expected \"<number> <unit>\" like {}, got \"{text}\"", dim.example()));
    }
    let Ok(value) = num.parse::<f64>() else {
        return Err(format!("`{num}` is not a number (in \"{text}\")"));
    };
    if !value.is_finite() {
        return Err(format!("`{num}` is not a finite number"));
    }
    if unit.is_empty() {
        return Err(format!("\"{text}\" has no unit; allowed units: {allowed}"));
    }
    match dim.factor(unit) {
        Some(factor) => Ok(Quantity { si: value * factor, unit: unit.to_string(), factor }),
        None => Err(format!("unit `{unit}` is not allowed here; allowed units: {allowed}")),
    }
}

/// Length of the leading decimal number (sign, digits, point, exponent) of `t`.
fn number_prefix_len(t: &str) -> usize {
    let b = t.as_bytes();
    let mut i = 0;
    if matches!(b.first(), Some(b'+' | b'-')) {
        i += 1;
    }
    while matches!(b.get(i), Some(c) if c.is_ascii_digit() || *c == b'.') {
        i += 1;
    }
    // Exponent only when digits follow, so that "5 e" or "1e" is not eaten.
    if matches!(b.get(i), Some(b'e' | b'E')) {
        let mut j = i + 1;
        if matches!(b.get(j), Some(b'+' | b'-')) {
            j += 1;
        }
        if matches!(b.get(j), Some(c) if c.is_ascii_digit()) {
            while matches!(b.get(j), Some(c) if c.is_ascii_digit()) {
                j += 1;
            }
            i = j;
        }
    }
    i
}

/// A number for messages: at most 6 significant digits, no trailing noise (`1000`, not
/// `999.9999999999999`).
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    let rounded: f64 = format!("{x:.5e}").parse().unwrap_or(x);
    let s = format!("{rounded}");
    if s.len() > 12 {
        format!("{rounded:e}")
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_physics::units::{DEG, DEG_PER_H, DEG_PER_MIN};

    fn si(text: &str, dim: Dim) -> f64 {
        parse(text, dim).map(|q| q.si).unwrap_or(f64::NAN)
    }

    #[test]
    fn angular_rates_in_every_accepted_spelling() {
        assert!((si("10 °/min", Dim::AngularRate) - 2.908_882_086_657_216e-3).abs() < 1e-15);
        assert_eq!(si("10 deg/min", Dim::AngularRate), 10.0 * DEG_PER_MIN);
        assert_eq!(si("15 °/h", Dim::AngularRate), 15.0 * DEG_PER_H);
        assert_eq!(si("2 deg/s", Dim::AngularRate), 2.0 * DEG);
        assert_eq!(si("0.5 rad/s", Dim::AngularRate), 0.5);
        assert_eq!(si("1e-3rad/s", Dim::AngularRate), 1e-3);
        assert_eq!(si("  -3 ° / s ", Dim::AngularRate), -3.0 * DEG);
        for u in Dim::AngularRate.accepted() {
            assert!(parse(&format!("1 {u}"), Dim::AngularRate).is_ok(), "{u}");
        }
    }

    #[test]
    fn other_dimensions() {
        assert_eq!(si("10 °/s²", Dim::AngularAccel), 10.0 * DEG);
        assert_eq!(si("10 deg/s2", Dim::AngularAccel), 10.0 * DEG);
        assert!((si("4 °C/min", Dim::TempRate) - 4.0 / 60.0).abs() < 1e-15);
        assert_eq!(si("1 C/h", Dim::TempRate), 1.0 / 3600.0);
        assert_eq!(si("12 min", Dim::Time), 720.0);
        assert_eq!(si("1.5 h", Dim::Time), 5400.0);
        assert_eq!(si("250 ms", Dim::Time), 0.25);
        assert_eq!(si("-40 °C", Dim::Temperature), -40.0);
        assert_eq!(si("20C", Dim::Temperature), 20.0);
        assert_eq!(si("0.5 K", Dim::TempDifference), 0.5);
        assert_eq!(si("2 kHz", Dim::Frequency), 2000.0);
        assert!(parse("1_000 Hz", Dim::Frequency).is_err());
        for d in [Dim::AngularAccel, Dim::TempRate, Dim::Time, Dim::Temperature, Dim::Frequency] {
            for u in d.accepted() {
                assert!(parse(&format!("1 {u}"), d).is_ok(), "{u} {d:?}");
            }
        }
    }

    #[test]
    fn errors_say_what_is_allowed() {
        let e = parse("10 furlong/s", Dim::AngularRate).expect_err("bad unit");
        assert_eq!(
            e,
            "unit `furlong/s` is not allowed here; allowed units: °/s, °/min, °/h, deg/s, \
             deg/min, deg/h, rad/s"
        );
        assert_eq!(
            parse("20", Dim::Temperature).expect_err("no unit"),
            "\"20\" has no unit; allowed units: °C, C, degC"
        );
        assert_eq!(
            parse("warm", Dim::Temperature).expect_err("no number"),
            "expected \"<number> <unit>\" like \"20 °C\", got \"warm\""
        );
        assert_eq!(
            parse("1.2.3 s", Dim::Time).expect_err("bad"),
            "`1.2.3` is not a number (in \"1.2.3 s\")"
        );
        assert!(parse("20 K", Dim::Temperature).is_err());
        assert!(parse("5 e", Dim::Time).is_err());
    }

    #[test]
    fn show_converts_back_to_the_users_unit() {
        let q = parse("2000 °/s", Dim::AngularRate).expect("parses");
        assert_eq!(q.show(1000.0 * DEG), "1000 °/s");
        assert_eq!(q.show_self(), "2000 °/s");
        assert_eq!(fmt_num(2.908_882_086_657_216e-3), "0.00290888");
        assert_eq!(fmt_num(1e-12), "1e-12");
    }
}
