//! [`CanBus`] over a Linux SocketCAN interface (`can0`, `vcan0`), with the `socketcan` crate's
//! tokio socket. Needs the cargo feature `socketcan` (on by default) and a kernel with AF_CAN;
//! without either, [`SocketCanBus::open`] fails with an `Unsupported` error that says which
//! (see [`is_af_can_missing`]).
//!
//! The interface's bit rate is set outside bench (`ip link set can0 type can bitrate 500000`).
//! Error frames from the kernel are not data: they set [`BusStatus::flags`]
//! (`BUS_ERROR`, and `OVERRUN` for a controller overflow) and are otherwise skipped.

use async_trait::async_trait;

use super::can::{BusStatus, CanBus, CanFrame};
use crate::{DeviceError, DeviceResult, ErrorKind};

/// Marker put into the message of the error returned when the kernel has no AF_CAN.
const NO_AF_CAN: &str = "the kernel has no CAN support (AF_CAN address family missing)";

/// Whether `e` (from [`SocketCanBus::open`]) says this machine cannot do SocketCAN at all (no
/// AF_CAN in the kernel, or bench built without the `socketcan` feature), as opposed to a
/// missing interface.
pub fn is_af_can_missing(e: &DeviceError) -> bool {
    e.kind() == ErrorKind::Unsupported
}

/// A SocketCAN interface.
pub struct SocketCanBus {
    iface: String,
    status: BusStatus,
    #[cfg(feature = "socketcan")]
    socket: socketcan::tokio::CanSocket,
}

impl SocketCanBus {
    /// Open interface `iface` (e.g. `can0`).
    #[cfg(feature = "socketcan")]
    pub fn open(iface: &str) -> DeviceResult<Self> {
        let socket = socketcan::tokio::CanSocket::open(iface).map_err(|e| {
            // The interface is looked up before the socket is made, so a kernel without AF_CAN
            // first shows as "no such device": probe by making a socket bound to any interface.
            let af_missing = e.raw_os_error() == Some(libc_eafnosupport())
                || <socketcan::CanSocket as socketcan::Socket>::open_iface(0)
                    .err()
                    .and_then(|p| p.raw_os_error())
                    == Some(libc_eafnosupport());
            if af_missing {
                DeviceError::new(ErrorKind::Unsupported, format!("socketcan {iface}: {NO_AF_CAN}"))
                    .with_source(e)
            } else {
                DeviceError::new(ErrorKind::Link, format!("cannot open socketcan {iface}: {e}"))
                    .with_source(e)
            }
        })?;
        Ok(Self { iface: iface.to_owned(), status: BusStatus::default(), socket })
    }

    /// Open interface `iface`: always `Unsupported` (built without the `socketcan` feature).
    #[cfg(not(feature = "socketcan"))]
    pub fn open(iface: &str) -> DeviceResult<Self> {
        Err(DeviceError::new(
            ErrorKind::Unsupported,
            format!("socketcan {iface}: bench-drivers was built without the `socketcan` feature"),
        ))
    }
}

/// `EAFNOSUPPORT` on Linux (the `libc` crate is not a dependency for one constant).
#[cfg(feature = "socketcan")]
fn libc_eafnosupport() -> i32 {
    97
}

#[cfg(feature = "socketcan")]
fn to_kernel(frame: &CanFrame) -> DeviceResult<socketcan::CanFrame> {
    use crate::protocol::slcan::CanId;
    use socketcan::{EmbeddedFrame, ExtendedId, Id, StandardId};
    let id: Option<Id> = match frame.id() {
        CanId::Standard(raw) => StandardId::new(raw).map(Id::Standard),
        CanId::Extended(raw) => ExtendedId::new(raw).map(Id::Extended),
    };
    let made = id.and_then(|id| {
        if frame.is_remote() {
            socketcan::CanFrame::new_remote(id, usize::from(frame.dlc()))
        } else {
            socketcan::CanFrame::new(id, frame.data())
        }
    });
    made.ok_or_else(|| {
        DeviceError::new(ErrorKind::OutOfRange, format!("frame {frame:?} is not a valid CAN frame"))
    })
}

#[cfg(feature = "socketcan")]
fn from_kernel(frame: &socketcan::CanFrame) -> Option<CanFrame> {
    use crate::protocol::slcan::CanId;
    use socketcan::{EmbeddedFrame, Id};
    let id = match frame.id() {
        Id::Standard(s) => CanId::Standard(s.as_raw()),
        Id::Extended(x) => CanId::Extended(x.as_raw()),
    };
    if frame.is_remote_frame() {
        CanFrame::new_remote(id, u8::try_from(frame.dlc()).ok()?).ok()
    } else {
        CanFrame::new_data(id, frame.data()).ok()
    }
}

#[async_trait]
impl CanBus for SocketCanBus {
    #[cfg(feature = "socketcan")]
    async fn send(&mut self, frame: &CanFrame) -> DeviceResult<()> {
        let k = to_kernel(frame)?;
        self.socket.write_frame(k).await.map_err(|e| {
            DeviceError::new(
                ErrorKind::Link,
                format!("socketcan {}: write failed: {e}", self.iface),
            )
            .with_source(e)
        })?;
        self.status.frames_tx += 1;
        Ok(())
    }

    #[cfg(not(feature = "socketcan"))]
    async fn send(&mut self, _frame: &CanFrame) -> DeviceResult<()> {
        Err(DeviceError::unsupported("socketcan"))
    }

    #[cfg(feature = "socketcan")]
    async fn recv(&mut self) -> DeviceResult<CanFrame> {
        use crate::protocol::slcan::status;
        loop {
            let f = self.socket.read_frame().await.map_err(|e| {
                DeviceError::new(
                    ErrorKind::Link,
                    format!("socketcan {}: read failed: {e}", self.iface),
                )
                .with_source(e)
            })?;
            if let socketcan::CanFrame::Error(err) = &f {
                let mut flags = status::BUS_ERROR;
                if socketcan::CanError::from(*err).controller().is_some() {
                    flags |= status::OVERRUN;
                    self.status.overruns += 1;
                }
                self.status.flags = flags;
                tracing::warn!(iface = %self.iface, ?err, "CAN error frame");
                continue;
            }
            match from_kernel(&f) {
                Some(frame) => {
                    self.status.frames_rx += 1;
                    return Ok(frame);
                }
                None => {
                    self.status.corrupt += 1;
                    return Err(DeviceError::new(
                        ErrorKind::Protocol,
                        format!("socketcan {}: unrepresentable frame {f:?}", self.iface),
                    ));
                }
            }
        }
    }

    #[cfg(not(feature = "socketcan"))]
    async fn recv(&mut self) -> DeviceResult<CanFrame> {
        Err(DeviceError::unsupported("socketcan"))
    }

    fn status(&self) -> BusStatus {
        self.status
    }

    fn describe(&self) -> String {
        format!("socketcan {}", self.iface)
    }
}

#[cfg(all(test, feature = "socketcan"))]
mod tests {
    use super::*;
    use crate::protocol::slcan::CanId;

    #[test]
    fn frames_convert_both_ways() {
        for f in [
            CanFrame::new_data(CanId::Standard(0x180), &[1, 2, 3, 4, 5, 6, 7, 8]).expect("f"),
            CanFrame::new_data(CanId::Extended(0x1ABC_DEF0), &[]).expect("f"),
            CanFrame::new_remote(CanId::Standard(0x7FF), 3).expect("f"),
        ] {
            let k = to_kernel(&f).expect("kernel frame");
            assert_eq!(from_kernel(&k), Some(f));
        }
    }
}
