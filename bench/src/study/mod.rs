//! Studies over many simulated seeds, truth known: the calibration's accuracy
//! ([`calibrate`]) and the diagnosis' false discoveries and recoveries ([`diagnose`]), on
//! bench's own recordings or with a lab's traits applied to them ([`lab`]).

pub mod calibrate;
pub mod diagnose;
pub mod lab;
