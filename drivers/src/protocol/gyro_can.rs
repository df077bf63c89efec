//! bench's own gyro CAN frame set: navigation-grade resolution over classic CAN (≤ 8 data
//! bytes, so it also runs over SLCAN). Public CAN gyro formats are too coarse (J1939 ARI:
//! 1/128 °/s per bit; Xsens: 2⁻⁹ rad/s per bit). Layouts are in `docs/protocols/gyro-can.md`;
//! all multi-byte fields are little-endian.
//!
//! | frame | default id | bytes |
//! |---|---|---|
//! | delta angle | 0x180 | 0: sequence low byte; 1–7: delta angle, signed 56-bit, LSB 2⁻⁴⁰ rad |
//! | housekeeping | 0x181 | 0–3: sequence u32; 4–5: status u16; 6–7: temperature i16, 0.01 °C |
//! | info | 0x182 | 0–3: sample period u32, ns; 4: angle LSB exponent (40); 5: version (1); 6–7: 0 |
//!
//! Per sample the gyro sends a delta-angle frame then a housekeeping frame with the same
//! sequence number; the info frame is sent about once a second. Resolution: 2⁻⁴⁰ rad ≈
//! 9.1e-13 rad per sample, i.e. 1.8e-11 rad/s at 20 Hz (a navigation-grade FOG's bias
//! stability is ~1e-8 rad/s). Range: ±2⁵⁵ LSB = ±32768 rad per sample, far above 500 °/s at any
//! rate down to 1 Hz (8.7 rad). [`SampleAssembler`] pairs the two frames of a sample by sequence
//! number.
//!
//! ```
//! use bench_drivers::protocol::gyro_can::{DeltaAngle, GyroCanFrame, GyroCanIds, Housekeeping, SampleAssembler};
//! let ids = GyroCanIds::default();
//! let a = GyroCanFrame::DeltaAngle(DeltaAngle::from_rad(7, 1e-9).unwrap());
//! let b = GyroCanFrame::Housekeeping(Housekeeping { seq: 7, status: 0, temp_centi_c: 2512 });
//! let mut asm = SampleAssembler::new(ids, 0.05);
//! assert!(asm.push(&a.encode(&ids).unwrap()).is_none());
//! let s = asm.push(&b.encode(&ids).unwrap()).unwrap().unwrap();
//! assert_eq!(s.seq, 7);
//! assert!((s.rate_rad_s - 2e-8).abs() < 1e-10);
//! assert!((s.temp_c - 25.12).abs() < 1e-9);
//! ```

use serde::{Deserialize, Serialize};

use super::slcan::{CanFrame, CanId};
use super::{finite, DecodeError, EncodeError};

/// Delta-angle LSB exponent: 1 LSB = 2^-ANGLE_LSB_EXP rad.
pub const ANGLE_LSB_EXP: u8 = 40;
/// Delta-angle LSB, rad.
pub const ANGLE_LSB_RAD: f64 = 1.0 / (1u64 << ANGLE_LSB_EXP) as f64;
/// Largest delta angle in LSB (signed 56-bit).
pub const DELTA_MAX: i64 = (1 << 55) - 1;
/// Smallest delta angle in LSB.
pub const DELTA_MIN: i64 = -(1 << 55);
/// Temperature LSB, °C.
pub const TEMP_LSB_C: f64 = 0.01;
/// Version carried by the info frame.
pub const PROTOCOL_VERSION: u8 = 1;

/// Status bits of the housekeeping frame.
pub mod status {
    /// The gyro flags the sample invalid.
    pub const INVALID: u16 = 1 << 0;
    /// Built-in test failure.
    pub const BIT_FAIL: u16 = 1 << 1;
    /// Rate beyond the gyro's input range during the sample.
    pub const OVER_RANGE: u16 = 1 << 2;
    /// Temperature sensor fault (temperature field not meaningful).
    pub const TEMP_FAULT: u16 = 1 << 3;
}

/// CAN identifiers of the frame set (configurable per bench).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GyroCanIds {
    /// Delta-angle frame id. Default 0x180.
    pub delta_angle: u32,
    /// Housekeeping frame id. Default 0x181.
    pub housekeeping: u32,
    /// Info frame id. Default 0x182.
    pub info: u32,
    /// Whether the ids are 29-bit. Default false (11-bit).
    pub extended: bool,
}

impl Default for GyroCanIds {
    fn default() -> Self {
        Self { delta_angle: 0x180, housekeeping: 0x181, info: 0x182, extended: false }
    }
}

impl GyroCanIds {
    fn id(&self, raw: u32) -> Result<CanId, EncodeError> {
        let id = if self.extended {
            CanId::extended(raw)
        } else {
            u16::try_from(raw).ok().and_then(CanId::standard)
        };
        id.ok_or_else(|| EncodeError::new("CAN id", raw, "outside the identifier range"))
    }

    /// Which frame of the set `id` is, if any.
    pub fn kind_of(&self, id: CanId) -> Option<FrameKind> {
        if id.is_extended() != self.extended {
            return None;
        }
        let raw = id.raw();
        [
            (self.delta_angle, FrameKind::DeltaAngle),
            (self.housekeeping, FrameKind::Housekeeping),
            (self.info, FrameKind::Info),
        ]
        .into_iter()
        .find(|(r, _)| *r == raw)
        .map(|(_, k)| k)
    }
}

/// The frames of the set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameKind {
    /// [`DeltaAngle`].
    DeltaAngle,
    /// [`Housekeeping`].
    Housekeeping,
    /// [`Info`].
    Info,
}

/// Delta angle over one sample interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeltaAngle {
    /// Low byte of the sample's sequence number.
    pub seq_lo: u8,
    /// Delta angle, LSB [`ANGLE_LSB_RAD`], within [`DELTA_MIN`]..=[`DELTA_MAX`].
    pub counts: i64,
}

impl DeltaAngle {
    /// From a delta angle in rad, rounded to the LSB.
    pub fn from_rad(seq: u32, delta_rad: f64) -> Result<Self, EncodeError> {
        let c = (finite("delta_rad", delta_rad)? / ANGLE_LSB_RAD).round();
        if c < DELTA_MIN as f64 || c > DELTA_MAX as f64 {
            return Err(EncodeError::new("delta_rad", delta_rad, "outside ±32768 rad"));
        }
        Ok(Self { seq_lo: seq.to_le_bytes()[0], counts: c as i64 })
    }

    /// The delta angle, rad.
    pub fn rad(&self) -> f64 {
        self.counts as f64 * ANGLE_LSB_RAD
    }
}

/// Sequence, status and temperature of one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Housekeeping {
    /// Sample sequence number (wraps at 2³²).
    pub seq: u32,
    /// Status bits ([`status`]); 0 = valid.
    pub status: u16,
    /// Gyro temperature, 0.01 °C.
    pub temp_centi_c: i16,
}

impl Housekeeping {
    /// Temperature, °C: the count divided by 100, so that 2506 reads 25.06 exactly as printed
    /// (× 0.01 gave 25.060000000000002).
    pub fn temp_c(&self) -> f64 {
        f64::from(self.temp_centi_c) / 100.0
    }

    /// Temperature in 0.01 °C from °C, rounded.
    pub fn temp_from_c(temp_c: f64) -> Result<i16, EncodeError> {
        let c = (finite("temp_c", temp_c)? / TEMP_LSB_C).round();
        if c < f64::from(i16::MIN) || c > f64::from(i16::MAX) {
            return Err(EncodeError::new("temp_c", temp_c, "outside ±327.67 °C"));
        }
        Ok(c as i16)
    }
}

/// Stream description, sent about once a second.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Info {
    /// Sample period, ns (20 Hz = 50 000 000).
    pub sample_period_ns: u32,
    /// Delta-angle LSB exponent ([`ANGLE_LSB_EXP`]).
    pub angle_lsb_exp: u8,
    /// Protocol version ([`PROTOCOL_VERSION`]).
    pub version: u8,
}

/// One frame of the set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GyroCanFrame {
    /// Delta angle.
    DeltaAngle(DeltaAngle),
    /// Sequence, status, temperature.
    Housekeeping(Housekeeping),
    /// Stream description.
    Info(Info),
}

impl GyroCanFrame {
    /// The CAN frame carrying this frame under `ids`.
    pub fn encode(&self, ids: &GyroCanIds) -> Result<CanFrame, EncodeError> {
        let mut d = [0u8; 8];
        let raw = match self {
            GyroCanFrame::DeltaAngle(a) => {
                if !(DELTA_MIN..=DELTA_MAX).contains(&a.counts) {
                    return Err(EncodeError::new("delta counts", a.counts, "outside 56 bits"));
                }
                d[0] = a.seq_lo;
                let le = a.counts.to_le_bytes();
                d[1..8].copy_from_slice(&le[..7]);
                ids.delta_angle
            }
            GyroCanFrame::Housekeeping(h) => {
                d[0..4].copy_from_slice(&h.seq.to_le_bytes());
                d[4..6].copy_from_slice(&h.status.to_le_bytes());
                d[6..8].copy_from_slice(&h.temp_centi_c.to_le_bytes());
                ids.housekeeping
            }
            GyroCanFrame::Info(i) => {
                d[0..4].copy_from_slice(&i.sample_period_ns.to_le_bytes());
                d[4] = i.angle_lsb_exp;
                d[5] = i.version;
                ids.info
            }
        };
        CanFrame::new_data(ids.id(raw)?, &d)
    }

    /// Decodes a CAN frame: `Ok(None)` for an id outside the set. Error offsets are byte
    /// indices in the frame's data.
    pub fn decode(ids: &GyroCanIds, frame: &CanFrame) -> Result<Option<Self>, DecodeError> {
        let Some(kind) = ids.kind_of(frame.id()) else {
            return Ok(None);
        };
        let d: [u8; 8] = frame.data().try_into().map_err(|_| {
            DecodeError::new(
                u64::from(frame.dlc()),
                format!("8 data bytes in a {kind:?} frame (id {:#x})", frame.id().raw()),
                frame.data(),
            )
        })?;
        let [b0, b1, b2, b3, b4, b5, b6, b7] = d;
        Ok(Some(match kind {
            FrameKind::DeltaAngle => {
                // Sign-extend the 56-bit field.
                let counts = i64::from_le_bytes([b1, b2, b3, b4, b5, b6, b7, 0]) << 8 >> 8;
                GyroCanFrame::DeltaAngle(DeltaAngle { seq_lo: b0, counts })
            }
            FrameKind::Housekeeping => GyroCanFrame::Housekeeping(Housekeeping {
                seq: u32::from_le_bytes([b0, b1, b2, b3]),
                status: u16::from_le_bytes([b4, b5]),
                temp_centi_c: i16::from_le_bytes([b6, b7]),
            }),
            FrameKind::Info => {
                if b4 != ANGLE_LSB_EXP {
                    return Err(DecodeError::new(
                        4,
                        format!("angle LSB exponent {ANGLE_LSB_EXP}"),
                        &[b4],
                    ));
                }
                GyroCanFrame::Info(Info {
                    sample_period_ns: u32::from_le_bytes([b0, b1, b2, b3]),
                    angle_lsb_exp: b4,
                    version: b5,
                })
            }
        }))
    }
}

/// One gyro sample assembled from a delta-angle and a housekeeping frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroCanSample {
    /// Sequence number.
    pub seq: u32,
    /// Delta angle over the sample interval, rad.
    pub delta_angle_rad: f64,
    /// Sample interval, s.
    pub interval_s: f64,
    /// Mean rate over the interval, rad/s.
    pub rate_rad_s: f64,
    /// Status bits ([`status`]).
    pub status: u16,
    /// Temperature, °C.
    pub temp_c: f64,
}

impl GyroCanSample {
    /// As a [`crate::GyroSample`] (status mapped onto [`bench_recording::status::gyro`]).
    pub fn to_gyro_sample(&self) -> crate::GyroSample {
        let mut st = 0;
        if self.status & (status::INVALID | status::OVER_RANGE) != 0 {
            st |= bench_recording::status::gyro::INVALID;
        }
        if self.status & status::BIT_FAIL != 0 {
            st |= bench_recording::status::gyro::BIT_FAIL;
        }
        crate::GyroSample {
            rate_rad_s: self.rate_rad_s,
            temperature_c: (self.status & status::TEMP_FAULT == 0).then_some(self.temp_c),
            seq: u64::from(self.seq),
            status: st,
            device_time: None,
        }
    }
}

/// Pairs delta-angle and housekeeping frames by sequence number into samples. Either order is
/// accepted; an unpaired frame is reported when the next frame of its kind arrives.
#[derive(Debug, Clone)]
pub struct SampleAssembler {
    ids: GyroCanIds,
    interval_s: f64,
    angle: Option<DeltaAngle>,
    house: Option<Housekeeping>,
}

impl SampleAssembler {
    /// An assembler for `ids` with a nominal sample interval (s), replaced by the interval in
    /// info frames as they arrive.
    pub fn new(ids: GyroCanIds, interval_s: f64) -> Self {
        Self { ids, interval_s, angle: None, house: None }
    }

    /// The sample interval in use, s.
    pub fn interval_s(&self) -> f64 {
        self.interval_s
    }

    fn try_pair(&mut self) -> Option<Result<GyroCanSample, DecodeError>> {
        let (a, h) = (self.angle?, self.house?);
        if a.seq_lo != h.seq.to_le_bytes()[0] {
            return None;
        }
        self.angle = None;
        self.house = None;
        let delta_angle_rad = a.rad();
        Some(Ok(GyroCanSample {
            seq: h.seq,
            delta_angle_rad,
            interval_s: self.interval_s,
            rate_rad_s: delta_angle_rad / self.interval_s,
            status: h.status,
            temp_c: h.temp_c(),
        }))
    }

    /// Feeds one received CAN frame; returns a sample when one is complete, an error for a
    /// malformed or unpaired frame, `None` otherwise (incl. frames with foreign ids).
    pub fn push(&mut self, frame: &CanFrame) -> Option<Result<GyroCanSample, DecodeError>> {
        let f = match GyroCanFrame::decode(&self.ids, frame) {
            Ok(Some(f)) => f,
            Ok(None) => return None,
            Err(e) => return Some(Err(e)),
        };
        let unpaired = match f {
            GyroCanFrame::Info(i) => {
                if i.sample_period_ns == 0 {
                    return Some(Err(DecodeError::new(
                        0,
                        "a non-zero sample period",
                        frame.data(),
                    )));
                }
                self.interval_s = f64::from(i.sample_period_ns) * 1e-9;
                return None;
            }
            GyroCanFrame::DeltaAngle(a) => self.angle.replace(a).map(|old| {
                DecodeError::new(
                    0,
                    format!("a housekeeping frame for sequence low byte {}", old.seq_lo),
                    &[old.seq_lo],
                )
            }),
            GyroCanFrame::Housekeeping(h) => self.house.replace(h).map(|old| {
                DecodeError::new(
                    0,
                    format!("a delta-angle frame for sequence {}", old.seq),
                    &old.seq.to_le_bytes(),
                )
            }),
        };
        if let Some(paired) = self.try_pair() {
            // A stale frame of the other kind was just superseded; the pair wins.
            return Some(paired);
        }
        unpaired.map(Err)
    }
}
