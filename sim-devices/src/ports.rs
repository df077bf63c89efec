//! Virtual ports: pseudo-terminal pairs and loopback TCP listeners on which the simulators
//! serve their devices' real protocols, so that the real drivers are tested end to end.

use std::io;

use tokio_serial::SerialPort;

/// A pseudo-terminal pair: the simulator serves on `server`; a driver opens `path`.
pub struct Pty {
    /// The simulator's end (the pty master).
    pub server: tokio_serial::SerialStream,
    /// Path a driver opens as its serial port (the pty slave), e.g. `/dev/pts/4`.
    pub path: String,
    /// The slave end, held open (non-exclusively) so the master never sees a hang-up while no
    /// driver is connected.
    _hold: tokio_serial::SerialStream,
}

impl Pty {
    /// Make a new pair. Needs a tokio runtime (the ends are registered with its reactor).
    pub fn new() -> io::Result<Self> {
        let (server, mut slave) = tokio_serial::SerialStream::pair().map_err(io::Error::other)?;
        slave.set_exclusive(false).map_err(io::Error::other)?;
        let path = slave
            .name()
            .ok_or_else(|| io::Error::other("pseudo-terminal without a device name"))?;
        Ok(Self { server, path, _hold: slave })
    }
}

/// Bind a TCP listener on 127.0.0.1 with an OS-chosen port (the address is in
/// `local_addr()`): tests never use fixed ports.
pub async fn loopback_listener() -> io::Result<tokio::net::TcpListener> {
    tokio::net::TcpListener::bind("127.0.0.1:0").await
}

#[cfg(test)]
mod tests {
    use super::*;
    use bench_drivers::transport::{Endpoint, SerialSettings};
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    #[tokio::test]
    async fn a_driver_opens_the_pty_by_path_and_bytes_flow_both_ways() {
        let mut pty = Pty::new().expect("pty");
        let ep = Endpoint::Serial(SerialSettings {
            path: pty.path.clone(),
            baud: 115_200,
            parity: Default::default(),
            data_bits: 8,
            stop_bits: 1,
        });
        let mut client = ep.open(std::time::Duration::from_secs(1)).await.expect("open");
        client.write_all(b"PRV 1,?\n").await.expect("write");
        let mut buf = [0u8; 8];
        pty.server.read_exact(&mut buf).await.expect("read");
        assert_eq!(&buf, b"PRV 1,?\n");
        pty.server.write_all(b"\x07\r").await.expect("write");
        let mut two = [0u8; 2];
        client.read_exact(&mut two).await.expect("read");
        assert_eq!(&two, b"\x07\r");
    }

    #[tokio::test]
    async fn loopback_tcp_uses_an_os_chosen_port() {
        let l = loopback_listener().await.expect("bind");
        let addr = l.local_addr().expect("addr");
        assert!(addr.ip().is_loopback() && addr.port() != 0);
        let ep = Endpoint::Tcp { addr: addr.to_string() };
        let (c, s) = tokio::join!(ep.open(std::time::Duration::from_secs(1)), l.accept());
        assert!(c.is_ok() && s.is_ok());
    }
}
