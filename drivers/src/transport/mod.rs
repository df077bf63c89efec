//! Byte-stream transports for the real drivers: serial ports (RS-232/RS-422, USB adapters,
//! pseudo-terminals) and TCP. Codecs in [`crate::protocol`] stay free of I/O; drivers combine
//! one codec with one [`Endpoint`].

use std::time::Duration;

use serde::{Deserialize, Serialize};
use tokio::io::{AsyncRead, AsyncWrite};

use crate::{DeviceError, ErrorKind};

/// A bidirectional byte stream a driver talks through.
pub trait ByteStream: AsyncRead + AsyncWrite + Unpin + Send + 'static {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send + 'static> ByteStream for T {}

/// A boxed [`ByteStream`].
pub type BoxStream = Box<dyn ByteStream>;

/// Parity of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Parity {
    /// No parity bit (the default).
    #[default]
    None,
    /// Even parity.
    Even,
    /// Odd parity.
    Odd,
}

/// How to open a serial port.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSettings {
    /// Device path, e.g. `/dev/ttyUSB0` or a pseudo-terminal `/dev/pts/3`.
    pub path: String,
    /// Baud rate.
    pub baud: u32,
    /// Parity (default none).
    #[serde(default)]
    pub parity: Parity,
    /// Data bits, 5..=8 (default 8).
    #[serde(default = "default_data_bits")]
    pub data_bits: u8,
    /// Stop bits, 1 or 2 (default 1).
    #[serde(default = "default_stop_bits")]
    pub stop_bits: u8,
}

fn default_data_bits() -> u8 {
    8
}
fn default_stop_bits() -> u8 {
    1
}

/// Where a device is reached.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Endpoint {
    /// A serial port.
    Serial(SerialSettings),
    /// A TCP server, `host:port`.
    Tcp {
        /// Address, e.g. `192.168.0.20:62000`.
        addr: String,
    },
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Endpoint::Serial(s) => write!(f, "serial {} at {} baud", s.path, s.baud),
            Endpoint::Tcp { addr } => write!(f, "tcp {addr}"),
        }
    }
}

impl Endpoint {
    /// Open the endpoint. Serial ports are opened non-exclusively (a pseudo-terminal's other
    /// end may hold it) and in raw mode; TCP connects within `timeout`.
    pub async fn open(&self, timeout: Duration) -> Result<BoxStream, DeviceError> {
        match self {
            Endpoint::Serial(s) => Ok(Box::new(open_serial(s)?)),
            Endpoint::Tcp { addr } => Ok(Box::new(connect_tcp(addr, timeout).await?)),
        }
    }
}

/// Open a serial port (tokio-serial, no libudev).
pub fn open_serial(s: &SerialSettings) -> Result<tokio_serial::SerialStream, DeviceError> {
    use tokio_serial::{DataBits, StopBits};
    let data_bits = match s.data_bits {
        5 => DataBits::Five,
        6 => DataBits::Six,
        7 => DataBits::Seven,
        8 => DataBits::Eight,
        n => {
            return Err(DeviceError::new(
                ErrorKind::OutOfRange,
                format!("serial {}: {n} data bits (allowed: 5, 6, 7, 8)", s.path),
            ))
        }
    };
    let stop_bits = match s.stop_bits {
        1 => StopBits::One,
        2 => StopBits::Two,
        n => {
            return Err(DeviceError::new(
                ErrorKind::OutOfRange,
                format!("serial {}: {n} stop bits (allowed: 1, 2)", s.path),
            ))
        }
    };
    let parity = match s.parity {
        Parity::None => tokio_serial::Parity::None,
        Parity::Even => tokio_serial::Parity::Even,
        Parity::Odd => tokio_serial::Parity::Odd,
    };
    let builder = tokio_serial::new(&s.path, s.baud)
        .data_bits(data_bits)
        .stop_bits(stop_bits)
        .parity(parity)
        .flow_control(tokio_serial::FlowControl::None)
        .exclusive(false);
    tokio_serial::SerialStream::open(&builder).map_err(|e| {
        DeviceError::new(ErrorKind::Link, format!("cannot open serial port {}: {e}", s.path))
            .with_source(e)
    })
}

/// Connect to a TCP server within `timeout`, with Nagle off (small request/response frames).
pub async fn connect_tcp(
    addr: &str,
    timeout: Duration,
) -> Result<tokio::net::TcpStream, DeviceError> {
    let stream = tokio::time::timeout(timeout, tokio::net::TcpStream::connect(addr))
        .await
        .map_err(|_| {
            DeviceError::new(
                ErrorKind::Timeout,
                format!("no TCP connection to {addr} within {timeout:?}"),
            )
        })?
        .map_err(|e| {
            DeviceError::new(ErrorKind::Link, format!("cannot connect to {addr}: {e}"))
                .with_source(e)
        })?;
    stream.set_nodelay(true).map_err(DeviceError::from)?;
    Ok(stream)
}

/// The serial ports of this machine (`bench ports`).
pub fn list_serial_ports() -> Result<Vec<String>, DeviceError> {
    tokio_serial::available_ports().map(|v| v.into_iter().map(|p| p.port_name).collect()).map_err(
        |e| {
            DeviceError::new(ErrorKind::Other, format!("cannot list serial ports: {e}"))
                .with_source(e)
        },
    )
}
