//! The simulated devices served over their real protocols on virtual ports
//! ([`crate::ports`]), with faults from a [`crate::faults::FaultSwitch`], so that the real
//! drivers are tested end to end.

pub mod bench;
pub mod chamber;
pub mod gyro;
pub mod table;
