//! The integration tests of the drivers crate, one module per subject, built as one test binary:
//! each binary links the whole dependency tree, so one instead of many saves minutes of CI.

mod protocol_kvh1750;
mod protocol_kvh_dsp3000;
mod protocol_modbus_map;
mod protocol_slcan;
mod protocol_table;
mod table_driver;
