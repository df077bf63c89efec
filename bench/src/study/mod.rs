//! Studies over many simulated seeds, truth known: the calibration's accuracy
//! ([`calibrate`]) and the diagnosis' false discoveries and recoveries ([`diagnose`]).

pub mod calibrate;
pub mod diagnose;
