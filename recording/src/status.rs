//! Status words recorded in the `status` fields of the recording (0 = ok / valid).

/// Gyro sample status bits (`/gyro/rate` `status`).
pub mod gyro {
    /// The device flagged the sample invalid.
    pub const INVALID: u32 = 1 << 0;
    /// The device's sample counter skipped: samples were lost before this one.
    pub const SEQ_GAP: u32 = 1 << 1;
    /// The device reports a built-in-test failure.
    pub const BIT_FAIL: u32 = 1 << 2;
    /// The sample was received after a corrupt frame was skipped.
    pub const AFTER_CORRUPT: u32 = 1 << 3;

    /// Whether a sample with this `status` is data an analysis uses: status 0, or exactly
    /// [`SEQ_GAP`] on a sample whose counter did skip (`seq_skipped`). That flag says samples
    /// were lost *before* this one; the sample itself is good, and leaving it out would widen
    /// the gap. Any other bit, or a [`SEQ_GAP`] the counter does not bear out, leaves it out.
    pub fn usable(status: u32, seq_skipped: bool) -> bool {
        status == 0 || (status == SEQ_GAP && seq_skipped)
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn a_gap_flag_marks_the_gap_before_a_good_sample() {
            assert!(usable(0, false) && usable(0, true));
            assert!(usable(SEQ_GAP, true));
            assert!(!usable(SEQ_GAP, false), "a gap the counter does not show");
            assert!(!usable(SEQ_GAP | AFTER_CORRUPT, true));
            assert!(!usable(INVALID, false) && !usable(BIT_FAIL, true));
        }
    }
}

/// Rate-table status bits (`/table/state` `status`).
pub mod table {
    /// Drive is off.
    pub const DRIVE_OFF: u32 = 1 << 0;
    /// Controller reports an alarm.
    pub const ALARM: u32 = 1 << 1;
    /// Interlock open.
    pub const INTERLOCK: u32 = 1 << 2;
    /// Rate not yet settled on the command (accelerating).
    pub const SLEWING: u32 = 1 << 3;
}

/// Chamber status bits (`/chamber/state` `status`).
pub mod chamber {
    /// Controller reports an alarm (sensor break, over-temperature).
    pub const ALARM: u32 = 1 << 0;
    /// Working set point is ramping toward the target.
    pub const RAMPING: u32 = 1 << 1;
    /// Heating or cooling output is saturated.
    pub const SATURATED: u32 = 1 << 2;
    /// The chamber door is open (a door switch the controller's register map reports).
    pub const DOOR_OPEN: u32 = 1 << 3;
}
