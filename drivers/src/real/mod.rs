//! Real device drivers: each implements a device trait over a [`crate::transport`] endpoint and
//! a codec from [`crate::protocol`].

pub mod can;
pub mod chamber;
pub mod gyro_can;
pub mod gyro_kvh;
pub mod gyro_link;
pub mod link;
pub mod slcan;
pub mod socketcan;
pub mod table;
