//! Faults the simulators inject on command, so that the drivers' and the orchestrator's
//! recovery and safe-state paths are tested end to end.
//!
//! One [`FaultSwitch`] per served device; the server consults it for every request or frame.
//! Tests hold a clone and flip faults while a run is in progress; `bench sim serve` exposes
//! them on its control port.

use std::sync::{Arc, Mutex, MutexGuard};

use serde::{Deserialize, Serialize};

/// A fault a served device can show.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "fault")]
pub enum Fault {
    /// Stop answering / sending (the driver sees timeouts).
    Silence,
    /// Corrupt one byte of every `n`-th reply or frame (bad CRC, garbled line).
    Corrupt {
        /// Period.
        every: u32,
    },
    /// Drop every `n`-th frame of a stream (gyro) or reply.
    Drop {
        /// Period.
        every: u32,
    },
    /// Close the connection once (TCP) or go silent for `seconds` (serial).
    Disconnect {
        /// How long the line stays dead, s (serial).
        seconds: f64,
    },
    /// Answer Modbus requests with this exception code (e.g. 4 = server device failure).
    ModbusException {
        /// Exception code.
        code: u8,
    },
    /// The table acknowledges rate commands but its rate does not follow.
    StuckTable,
    /// The table controller drops its drive with an alarm (an amplifier fault), once, at the
    /// next request with the drive on: the axis decelerates to rest, the mode reads off, and
    /// mode and motion commands are refused with a drive alarm until the alarms are cleared.
    DriveAlarm,
    /// The chamber overshoots new set points by this much, °C.
    ChamberOvershoot {
        /// Overshoot, °C.
        overshoot_c: f64,
    },
}

/// The faults active on one device, shared between the server and whoever injects them.
#[derive(Debug, Clone, Default)]
pub struct FaultSwitch(Arc<Mutex<Vec<Fault>>>);

impl FaultSwitch {
    /// No faults.
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> MutexGuard<'_, Vec<Fault>> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Switch a fault on (replacing one of the same kind).
    pub fn inject(&self, fault: Fault) {
        let mut v = self.lock();
        v.retain(|f| std::mem::discriminant(f) != std::mem::discriminant(&fault));
        v.push(fault);
    }

    /// Switch every fault off.
    pub fn clear(&self) {
        self.lock().clear();
    }

    /// Switch off faults of the same kind as `fault`.
    pub fn remove(&self, fault: &Fault) {
        self.lock().retain(|f| std::mem::discriminant(f) != std::mem::discriminant(fault));
    }

    /// The active faults.
    pub fn active(&self) -> Vec<Fault> {
        self.lock().clone()
    }

    /// Whether a fault of this kind is on; returns it.
    pub fn find(&self, pred: impl Fn(&Fault) -> bool) -> Option<Fault> {
        self.lock().iter().copied().find(|f| pred(f))
    }

    /// Shorthand: is [`Fault::Silence`] on?
    pub fn silent(&self) -> bool {
        self.find(|f| matches!(f, Fault::Silence)).is_some()
    }
}

/// Counts frames for the `every n-th` faults.
#[derive(Debug, Default, Clone)]
pub struct FaultCounter(u64);

impl FaultCounter {
    /// Count one frame; true when it is the `every`-th.
    pub fn tick(&mut self, every: u32) -> bool {
        self.0 += 1;
        every > 0 && self.0.is_multiple_of(u64::from(every))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inject_replaces_same_kind_and_clear_removes_all() {
        let f = FaultSwitch::new();
        f.inject(Fault::Corrupt { every: 3 });
        f.inject(Fault::Corrupt { every: 5 });
        f.inject(Fault::Silence);
        assert_eq!(f.active(), vec![Fault::Corrupt { every: 5 }, Fault::Silence]);
        assert!(f.silent());
        f.remove(&Fault::Silence);
        assert!(!f.silent());
        f.clear();
        assert!(f.active().is_empty());
    }

    #[test]
    fn counter_fires_every_nth() {
        let mut c = FaultCounter::default();
        let fired: Vec<bool> = (0..6).map(|_| c.tick(3)).collect();
        assert_eq!(fired, vec![false, false, true, false, false, true]);
    }

    #[test]
    fn faults_parse_from_json_commands() {
        let f: Fault = serde_json::from_str(r#"{"fault":"corrupt","every":4}"#).expect("parses");
        assert_eq!(f, Fault::Corrupt { every: 4 });
        let f: Fault = serde_json::from_str(r#"{"fault":"stuck_table"}"#).expect("parses");
        assert_eq!(f, Fault::StuckTable);
        let f: Fault = serde_json::from_str(r#"{"fault":"drive_alarm"}"#).expect("parses");
        assert_eq!(f, Fault::DriveAlarm);
    }
}
