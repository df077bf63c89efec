//! Chamber controller register maps as data, and the conversion of 16-bit register words to and
//! from °C. The Modbus framing itself is tokio-modbus's job (in the transport); this module
//! only says which registers to read and write and how to interpret the words.
//!
//! A map is serde-deserialisable from a bench config, or taken from a preset
//! ([`Preset::WatlowF4`], [`Preset::WatlowF4T`], [`Preset::Eurotherm3216`]); addresses are the
//! 0-based protocol addresses put in the Modbus PDU, as public drivers use them.
//!
//! **EEPROM wear**: some controllers keep the set point in EEPROM (Eurotherm 3216: target set
//! point 2 and SP1/SP2 24/25, ~100 000 writes). A ramp written there every few seconds would
//! wear it out in days, so [`RegisterMap::set_point_writes`] never targets a register listed in
//! `eeprom_registers`, and the Eurotherm preset writes through the remote (comms) set point 26.
//!
//! ```
//! use bench_drivers::protocol::modbus_map::{Preset, RegisterMap};
//! let f4t = RegisterMap::preset(Preset::WatlowF4T);
//! // F4T: float32, low word first.
//! let words = f4t.encoding.encode(-40.0, 0).unwrap();
//! assert_eq!(words, vec![0x0000, 0xC220]);
//! assert_eq!(f4t.encoding.decode(&words, 0).unwrap(), -40.0);
//! ```

use serde::{Deserialize, Serialize};

use super::{finite, DecodeError, EncodeError};

/// Order of the two 16-bit words of a 32-bit float.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WordOrder {
    /// Low-order word at the lower address (Watlow F4T).
    LowWordFirst,
    /// High-order word at the lower address (Modbus convention).
    HighWordFirst,
}

/// Where the number of implied decimals of an int16 value comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Decimals {
    /// A fixed number of decimals (0..=4).
    Fixed(u8),
    /// Read from this register at connection time (Watlow F4: 606).
    Register(u16),
}

/// How a temperature is held in registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum ValueEncoding {
    /// One signed 16-bit register, value × 10^decimals.
    Int16 {
        /// Implied decimals.
        decimals: Decimals,
    },
    /// Two registers holding an IEEE-754 float32.
    Float32 {
        /// Word order.
        word_order: WordOrder,
    },
}

/// Largest number of implied decimals accepted.
pub const MAX_DECIMALS: u8 = 4;

impl ValueEncoding {
    /// Registers one value occupies.
    pub fn word_count(&self) -> u16 {
        match self {
            ValueEncoding::Int16 { .. } => 1,
            ValueEncoding::Float32 { .. } => 2,
        }
    }

    /// Decodes a value (°C) from its register words; `decimals` is the number of implied
    /// decimals (ignored for floats; for [`Decimals::Register`] pass the value read there).
    /// Error offsets are word indices.
    pub fn decode(&self, words: &[u16], decimals: u8) -> Result<f64, DecodeError> {
        let bytes = || words.iter().flat_map(|w| w.to_be_bytes()).collect::<Vec<_>>();
        match *self {
            ValueEncoding::Int16 { .. } => {
                if decimals > MAX_DECIMALS {
                    return Err(DecodeError::new(0, "0..=4 implied decimals", &[decimals]));
                }
                let [w] = words else {
                    return Err(DecodeError::new(0, "exactly 1 register word", &bytes()));
                };
                Ok(f64::from(*w as i16) / 10f64.powi(i32::from(decimals)))
            }
            ValueEncoding::Float32 { word_order } => {
                let [a, b] = words else {
                    return Err(DecodeError::new(0, "exactly 2 register words", &bytes()));
                };
                let (hi, lo) = match word_order {
                    WordOrder::LowWordFirst => (*b, *a),
                    WordOrder::HighWordFirst => (*a, *b),
                };
                let v = f32::from_bits((u32::from(hi) << 16) | u32::from(lo));
                if v.is_finite() {
                    Ok(f64::from(v))
                } else {
                    Err(DecodeError::new(0, "a finite float32", &bytes()))
                }
            }
        }
    }

    /// Encodes a value (°C) into register words, rounding int16 values to the implied decimals.
    pub fn encode(&self, value: f64, decimals: u8) -> Result<Vec<u16>, EncodeError> {
        let v = finite("value", value)?;
        match *self {
            ValueEncoding::Int16 { .. } => {
                if decimals > MAX_DECIMALS {
                    return Err(EncodeError::new("decimals", decimals, "more than 4"));
                }
                let scaled = (v * 10f64.powi(i32::from(decimals))).round();
                if scaled < f64::from(i16::MIN) || scaled > f64::from(i16::MAX) {
                    return Err(EncodeError::new(
                        "value",
                        value,
                        "outside int16 at these decimals",
                    ));
                }
                Ok(vec![scaled as i16 as u16])
            }
            ValueEncoding::Float32 { word_order } => {
                let f = v as f32;
                if !f.is_finite() {
                    return Err(EncodeError::new("value", value, "outside float32"));
                }
                let bits = f.to_bits();
                let (hi, lo) = ((bits >> 16) as u16, bits as u16);
                Ok(match word_order {
                    WordOrder::LowWordFirst => vec![lo, hi],
                    WordOrder::HighWordFirst => vec![hi, lo],
                })
            }
        }
    }
}

/// A register and a raw word: a write done once when taking control (e.g. selecting the remote
/// set point), or a value a register must hold ([`RegisterMap::celsius_check`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegisterWrite {
    /// Register address.
    pub register: u16,
    /// Raw word to write.
    pub value: u16,
}

/// Bits of a status register that report one condition (an alarm, the door open): the
/// condition holds while any bit of `mask` is set in the register's word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StatusBits {
    /// Register address, read (function 3, one word) with every poll.
    pub register: u16,
    /// The bits that report the condition.
    pub mask: u16,
}

impl StatusBits {
    /// Whether `word` reports the condition.
    pub fn set_in(&self, word: u16) -> bool {
        word & self.mask != 0
    }
}

/// A chamber controller's register map.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegisterMap {
    /// Model, for logs.
    pub model: String,
    /// How temperatures are encoded.
    pub encoding: ValueEncoding,
    /// Process value (measured temperature).
    pub process_value: u16,
    /// Register the host writes the set point to (cyclically during a ramp).
    pub set_point: u16,
    /// Working (ramping) set point, read-only, if the controller has one.
    #[serde(default)]
    pub working_set_point: Option<u16>,
    /// Set-point rate limit, if the controller has one (°C/min on the Eurotherm 3216 — check the
    /// controller's rate units).
    #[serde(default)]
    pub ramp_rate: Option<u16>,
    /// Writes done once when taking control (e.g. Eurotherm: select the remote set point).
    #[serde(default)]
    pub on_connect: Vec<RegisterWrite>,
    /// Registers stored in EEPROM: never written cyclically.
    #[serde(default)]
    pub eeprom_registers: Vec<u16>,
    /// A register that must hold this word for temperatures to be in °C, checked at connection
    /// (Watlow F4: 901 = 1; 0 means °F, and every temperature register would be in °F).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub celsius_check: Option<RegisterWrite>,
    /// Where the controller reports an alarm (sensor break, over-temperature cut-out): the
    /// reading's status then has `ALARM`, and the run aborts (`chamber_alarm`). No preset has
    /// it: the public facts give no address; a lab adds its controller's to a custom map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alarm: Option<StatusBits>,
    /// Where the controller reports the door open (`DOOR_OPEN`, `chamber_door_open`); as
    /// `alarm`, in custom maps only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub door: Option<StatusBits>,
}

/// Built-in maps (device-facts.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// Watlow F4: int16, decimals from register 606, PV 100, SP 300; 901 must be 1 (°C).
    #[serde(rename = "watlow_f4")]
    WatlowF4,
    /// Watlow F4T loop 1: float32 low word first, PV 2820, SP 2782, WSP 2810.
    #[serde(rename = "watlow_f4t")]
    WatlowF4T,
    /// Eurotherm 3216: int16 (1 decimal by default), PV 1, set point written to the remote SP
    /// 26 (selected with 276 = 1), working SP 5, SP rate limit 35; registers 2, 24, 25 are EEPROM.
    #[serde(rename = "eurotherm_3216")]
    Eurotherm3216,
}

/// A map that would wear out EEPROM or is otherwise unusable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("register map {model}: {problem}")]
pub struct MapError {
    /// Model of the map.
    pub model: String,
    /// What is wrong.
    pub problem: String,
}

impl RegisterMap {
    /// A built-in map.
    pub fn preset(p: Preset) -> Self {
        match p {
            Preset::WatlowF4 => Self {
                model: "Watlow F4".into(),
                encoding: ValueEncoding::Int16 { decimals: Decimals::Register(606) },
                process_value: 100,
                set_point: 300,
                working_set_point: None,
                ramp_rate: None,
                on_connect: Vec::new(),
                eeprom_registers: Vec::new(),
                celsius_check: Some(RegisterWrite { register: 901, value: 1 }),
                alarm: None,
                door: None,
            },
            Preset::WatlowF4T => Self {
                model: "Watlow F4T".into(),
                encoding: ValueEncoding::Float32 { word_order: WordOrder::LowWordFirst },
                process_value: 2820,
                set_point: 2782,
                working_set_point: Some(2810),
                ramp_rate: None,
                on_connect: Vec::new(),
                eeprom_registers: Vec::new(),
                celsius_check: None,
                alarm: None,
                door: None,
            },
            Preset::Eurotherm3216 => Self {
                model: "Eurotherm 3216".into(),
                encoding: ValueEncoding::Int16 { decimals: Decimals::Fixed(1) },
                process_value: 1,
                set_point: 26,
                working_set_point: Some(5),
                ramp_rate: Some(35),
                on_connect: vec![RegisterWrite { register: 276, value: 1 }],
                eeprom_registers: vec![2, 24, 25],
                celsius_check: None,
                alarm: None,
                door: None,
            },
        }
    }

    /// Checks the map: the cyclic set-point register must not be an EEPROM register, fixed
    /// decimals must be at most [`MAX_DECIMALS`], and a status mask must have a bit.
    pub fn validate(&self) -> Result<(), MapError> {
        let fail = |problem: String| Err(MapError { model: self.model.clone(), problem });
        if self.eeprom_registers.contains(&self.set_point) {
            return fail(format!(
                "set point register {} is in EEPROM; write through a remote/comms set point",
                self.set_point
            ));
        }
        for (name, bits) in [("alarm", self.alarm), ("door", self.door)] {
            if bits.is_some_and(|b| b.mask == 0) {
                return fail(format!("{name} mask 0 reports nothing"));
            }
        }
        if let ValueEncoding::Int16 { decimals: Decimals::Fixed(d) } = self.encoding {
            if d > MAX_DECIMALS {
                return fail(format!("{d} implied decimals (at most {MAX_DECIMALS})"));
            }
        }
        Ok(())
    }

    /// Register to read the implied decimals from, if any.
    pub fn decimals_register(&self) -> Option<u16> {
        match self.encoding {
            ValueEncoding::Int16 { decimals: Decimals::Register(r) } => Some(r),
            _ => None,
        }
    }

    /// Implied decimals when fixed by the map (`None`: read [`Self::decimals_register`]).
    pub fn fixed_decimals(&self) -> Option<u8> {
        match self.encoding {
            ValueEncoding::Int16 { decimals: Decimals::Fixed(d) } => Some(d),
            ValueEncoding::Float32 { .. } => Some(0),
            ValueEncoding::Int16 { decimals: Decimals::Register(_) } => None,
        }
    }

    /// `(first register, count)` to read the process value.
    pub fn process_value_read(&self) -> (u16, u16) {
        (self.process_value, self.encoding.word_count())
    }

    /// The register writes that set the set point to `temp_c` — one write starting at
    /// [`RegisterMap::set_point`] (1 or 2 words). Refuses an EEPROM register.
    pub fn set_point_writes(
        &self,
        temp_c: f64,
        decimals: u8,
    ) -> Result<(u16, Vec<u16>), EncodeError> {
        if self.eeprom_registers.contains(&self.set_point) {
            return Err(EncodeError::new(
                "set point register",
                self.set_point,
                "is in EEPROM and must not be written cyclically",
            ));
        }
        Ok((self.set_point, self.encoding.encode(temp_c, decimals)?))
    }
}
/// Units of the controller's set-point rate-limit register.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum RateUnits {
    /// °C per second.
    PerSecond,
    /// °C per minute (the default; Eurotherm 3216 as commonly configured).
    #[default]
    PerMinute,
    /// °C per hour.
    PerHour,
}

impl RateUnits {
    /// Seconds in one unit of time.
    pub fn seconds(self) -> f64 {
        match self {
            RateUnits::PerSecond => 1.0,
            RateUnits::PerMinute => 60.0,
            RateUnits::PerHour => 3600.0,
        }
    }
}
