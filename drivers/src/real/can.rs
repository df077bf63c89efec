//! A CAN bus as the gyro driver sees it: send a classic frame, receive the next one. Two
//! transports implement it: [`super::slcan::SlcanBus`] (a Lawicel SLCAN adapter on a serial
//! port) and [`super::socketcan::SocketCanBus`] (a Linux SocketCAN interface, cargo feature
//! `socketcan`).
//!
//! Frames are the codec's [`CanFrame`] (11- or 29-bit id, data or remote, up to 8 bytes), so a
//! frame decoded from SLCAN text and one read from a kernel socket are the same value.

use async_trait::async_trait;

use crate::DeviceResult;

pub use crate::protocol::slcan::{CanFrame, CanId};

/// Health of a bus as the transport knows it. Counters only grow.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusStatus {
    /// Last status flags the adapter reported (SLCAN `Fxx`, bits in
    /// [`crate::protocol::slcan::status`]; SocketCAN error frames map onto the same bits).
    pub flags: u8,
    /// Status reports with the overrun or RX-FIFO-full flag: frames were lost in the adapter.
    pub overruns: u64,
    /// Received bytes or frames that could not be decoded (each also returned once from
    /// [`CanBus::recv`] as a `Protocol` error).
    pub corrupt: u64,
    /// Error replies (SLCAN BEL) to commands, transmissions or status polls.
    pub adapter_errors: u64,
    /// Frames received.
    pub frames_rx: u64,
    /// Frames sent.
    pub frames_tx: u64,
}

/// A CAN bus: send and receive classic CAN frames.
///
/// Errors: `Protocol` from [`CanBus::recv`] is one undecodable frame or line — the bus stays
/// usable and the next call carries on; `Link` means the port or socket failed.
#[async_trait]
pub trait CanBus: Send {
    /// Queue `frame` for transmission. Returns once the bytes are handed to the port or socket;
    /// it does not wait for an acknowledgement (a refusal shows in [`BusStatus::adapter_errors`]).
    async fn send(&mut self, frame: &CanFrame) -> DeviceResult<()>;

    /// Wait for the next received frame. Blocks until one arrives (no timeout of its own: wrap
    /// it in one). Cancel-safe: dropping the future loses no frame.
    async fn recv(&mut self) -> DeviceResult<CanFrame>;

    /// Counters and the last status flags.
    fn status(&self) -> BusStatus;

    /// Transport and address, e.g. `slcan /dev/ttyACM0 at 500 kbit/s`.
    fn describe(&self) -> String;

    /// Take the bus off the CAN (SLCAN `C`). Default: nothing to do.
    async fn close(&mut self) -> DeviceResult<()> {
        Ok(())
    }
}

#[async_trait]
impl<B: CanBus + ?Sized> CanBus for Box<B> {
    async fn send(&mut self, frame: &CanFrame) -> DeviceResult<()> {
        (**self).send(frame).await
    }
    async fn recv(&mut self) -> DeviceResult<CanFrame> {
        (**self).recv().await
    }
    fn status(&self) -> BusStatus {
        (**self).status()
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
    async fn close(&mut self) -> DeviceResult<()> {
        (**self).close().await
    }
}
