//! `time_offset`: the gyro's time tags are offset from the table's.

use super::{
    Columns, EffectSample, Family, LinearEffect, Owner, Param, Procedure, Reported, Rival, Role,
};

/// Time-tag offset of the gyro against the table: the input over `[t − dt − δ, t − δ]`
/// instead of `[t − dt, t]` (δ > 0 when the gyro's stamps are late).
pub struct TimeOffset;

impl LinearEffect for TimeOffset {
    fn key(&self) -> &'static str {
        "time_offset"
    }
    fn owner(&self) -> Owner {
        Owner::Clock
    }
    fn description(&self) -> &'static str {
        "gyro and table time tags are offset: the gyro's rate is compared with the \
         table's motion at the wrong instant, spiking at every rate change"
    }
    fn shape(&self) -> &'static str {
        "dΩ/dt (a time offset)"
    }
    fn formula(&self) -> &'static str {
        "input over `[t − dt − δ, t − δ]` instead of `[t − dt, t]`"
    }
    fn params(&self) -> &'static [Param] {
        const P: &[Param] = &[Param::finite("offset_s", "s", Role::Coefficient(0))];
        P
    }
    fn linear_count(&self) -> usize {
        0
    }
    fn regressors(&self, _s: &EffectSample, _out: &mut [f64]) {
        // Applied to the table's motion (the time-shifted angle), not added to the output.
    }
    fn columns(&self) -> Columns {
        Columns::TimeOffset
    }
    fn family(&self) -> Family {
        Family::RateChange
    }
    fn rivals(&self) -> &'static [Rival] {
        &[]
    }
    fn separated_by(&self) -> Procedure {
        Procedure::TurnsAtTwoRates
    }
    fn reported(&self) -> &'static [Reported] {
        &[Reported::Linear { name: "offset_s", unit: "s", index: 0 }]
    }
}
