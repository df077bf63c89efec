//! [`CanBus`] over a Lawicel SLCAN adapter on a serial port (USB-CAN dongles, or the simulator's
//! pseudo-terminal).
//!
//! Opening sends `C` (close whatever a previous session left open; a BEL answer is expected
//! when the channel was closed and ignored), `Sn` (bit rate), `V` (version, optional: a BEL or
//! no answer is tolerated) and `O` (open). While open, received `t`/`T`/`r`/`R` lines become
//! frames; the adapter's status flags are polled with `F` every
//! [`SlcanOptions::status_poll`], and an overrun or RX-FIFO-full flag is counted in
//! [`BusStatus::overruns`]. A BEL is reported with the stream byte offset at which it arrived.
//! [`CanBus::close`] sends `C`; dropping the bus without closing tries to send `C` without
//! waiting.
//!
//! Writes go through an output buffer drained with single `write` calls, so [`CanBus::recv`]
//! stays cancel-safe although it also sends the status polls.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use async_trait::async_trait;
use futures::FutureExt;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use super::can::{BusStatus, CanBus, CanFrame};
use crate::protocol::slcan::{self, AdapterMessage, Bitrate, HostCommand, HostDecoder, BEL};
use crate::transport::{open_serial, ByteStream, SerialSettings};
use crate::{Clock, DeviceError, DeviceResult, ErrorKind};

/// How to run the adapter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlcanOptions {
    /// CAN bit rate (default 500 kbit/s).
    pub bitrate: Bitrate,
    /// Status-flag poll period, bench time; `None` = never poll (default 1 s).
    pub status_poll: Option<Duration>,
    /// How long a command (`C`, `Sn`, `V`, `O`) may take to be answered, bench time (default
    /// 1 s).
    pub command_timeout: Duration,
}

impl Default for SlcanOptions {
    fn default() -> Self {
        Self {
            bitrate: Bitrate::K500,
            status_poll: Some(Duration::from_secs(1)),
            command_timeout: Duration::from_secs(1),
        }
    }
}

/// An SLCAN adapter, opened on the CAN bus.
pub struct SlcanBus<S: ByteStream> {
    stream: S,
    name: String,
    clock: Arc<dyn Clock>,
    options: SlcanOptions,
    dec: HostDecoder,
    /// Bytes fed to the decoder so far (stream offset of the next byte).
    fed: u64,
    /// Stream offsets of BELs fed but not yet taken out of the decoder, in order.
    bel_offsets: VecDeque<u64>,
    rx: VecDeque<CanFrame>,
    out: Vec<u8>,
    status: BusStatus,
    next_poll: Option<Duration>,
    open: bool,
    version: Option<(u8, u8)>,
}

/// What a command waits for.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Expect {
    Ok,
    Version,
}

impl SlcanBus<tokio_serial::SerialStream> {
    /// Open the serial port `serial` and the adapter on it.
    pub async fn open_serial(
        serial: &SerialSettings,
        options: SlcanOptions,
        clock: Arc<dyn Clock>,
    ) -> DeviceResult<Self> {
        let stream = open_serial(serial)?;
        Self::open(stream, serial.path.clone(), options, clock).await
    }
}

impl<S: ByteStream> SlcanBus<S> {
    /// Open the adapter on an already open byte stream; `name` is used in messages.
    pub async fn open(
        stream: S,
        name: impl Into<String>,
        options: SlcanOptions,
        clock: Arc<dyn Clock>,
    ) -> DeviceResult<Self> {
        let mut bus = Self {
            stream,
            name: name.into(),
            clock,
            options,
            dec: HostDecoder::new(),
            fed: 0,
            bel_offsets: VecDeque::new(),
            rx: VecDeque::new(),
            out: Vec::new(),
            status: BusStatus::default(),
            next_poll: None,
            open: false,
            version: None,
        };
        // A previous session may have left the channel open: close it. The adapter answers
        // BEL when it was already closed, which is fine.
        match bus.command(HostCommand::Close, Expect::Ok).await {
            Ok(_) => {}
            Err(e) if e.kind() == ErrorKind::Protocol => {
                tracing::debug!(adapter = %bus.name, "C refused (channel was closed)");
            }
            Err(e) => return Err(e),
        }
        bus.command(HostCommand::SetBitrate(options.bitrate), Expect::Ok).await?;
        match bus.command(HostCommand::Version, Expect::Version).await {
            Ok(AdapterMessage::Version { hardware, software }) => {
                bus.version = Some((hardware, software));
            }
            Ok(_) | Err(_) => tracing::debug!(adapter = %bus.name, "no version reply"),
        }
        bus.command(HostCommand::Open, Expect::Ok).await?;
        bus.open = true;
        bus.next_poll = options.status_poll.map(|p| bus.clock.now() + p);
        tracing::info!(adapter = %bus.name, bitrate = options.bitrate.bits_per_s(), "SLCAN open");
        Ok(bus)
    }

    /// The adapter's hardware and software versions (`V`), if it answered.
    pub fn version(&self) -> Option<(u8, u8)> {
        self.version
    }

    fn err(&self, kind: ErrorKind, what: impl std::fmt::Display) -> DeviceError {
        DeviceError::new(kind, format!("SLCAN adapter {}: {what}", self.name))
    }

    /// Read once from the port into the decoder. Cancel-safe.
    async fn fill(&mut self) -> DeviceResult<()> {
        let mut buf = [0u8; 4096];
        let n =
            self.stream.read(&mut buf).await.map_err(|e| {
                self.err(ErrorKind::Link, format!("read failed: {e}")).with_source(e)
            })?;
        if n == 0 {
            return Err(self.err(ErrorKind::Link, "port closed (end of stream)"));
        }
        let got = buf.get(..n).unwrap_or_default();
        for (i, b) in got.iter().enumerate() {
            if *b == BEL {
                self.bel_offsets.push_back(self.fed + i as u64);
            }
        }
        self.fed += n as u64;
        self.dec.push(got);
        Ok(())
    }

    /// Write the output buffer out. Cancel-safe: each completed `write` is taken off the buffer.
    async fn flush_out(&mut self) -> DeviceResult<()> {
        while !self.out.is_empty() {
            let n = self.stream.write(&self.out).await.map_err(|e| {
                self.err(ErrorKind::Link, format!("write failed: {e}")).with_source(e)
            })?;
            if n == 0 {
                return Err(self.err(ErrorKind::Link, "port closed (write returned 0)"));
            }
            self.out.drain(..n.min(self.out.len()));
        }
        self.stream
            .flush()
            .await
            .map_err(|e| self.err(ErrorKind::Link, format!("flush failed: {e}")).with_source(e))
    }

    fn note_status(&mut self, flags: u8) {
        self.status.flags = flags;
        if flags & (slcan::status::OVERRUN | slcan::status::RX_FIFO_FULL) != 0 {
            self.status.overruns += 1;
            tracing::warn!(adapter = %self.name, flags, "SLCAN adapter reports an overrun");
        }
    }

    /// Send `cmd` and wait for its answer (frames arriving meanwhile are queued).
    async fn command(&mut self, cmd: HostCommand, expect: Expect) -> DeviceResult<AdapterMessage> {
        let text = String::from_utf8_lossy(&cmd.encode()).trim_end().to_owned();
        self.out.extend_from_slice(&cmd.encode());
        self.flush_out().await?;
        let clock = self.clock.clone();
        let limit = self.options.command_timeout;
        let answer = crate::clock::timeout(&*clock, limit, async {
            loop {
                while let Some(m) = self.dec.next_message() {
                    match m {
                        Ok(AdapterMessage::Received { frame, .. }) => {
                            self.status.frames_rx += 1;
                            if self.open {
                                self.rx.push_back(frame);
                            }
                        }
                        Ok(AdapterMessage::Error) => {
                            self.status.adapter_errors += 1;
                            let at = self.bel_offsets.pop_front().unwrap_or(self.fed);
                            return Err(self.err(
                                ErrorKind::Protocol,
                                format!("answered BEL (error) to `{text}` at stream byte {at}"),
                            ));
                        }
                        Ok(AdapterMessage::Status(f)) => {
                            self.note_status(f);
                            if expect == Expect::Ok {
                                continue;
                            }
                        }
                        Ok(m @ AdapterMessage::Version { .. }) if expect == Expect::Version => {
                            return Ok(m);
                        }
                        Ok(m @ AdapterMessage::Ok) if expect == Expect::Ok => return Ok(m),
                        Ok(other) => {
                            tracing::debug!(adapter = %self.name, ?other, "unexpected reply ignored");
                        }
                        // Before the channel is open, a partial line left in the port is
                        // expected: skip it.
                        Err(e) => {
                            tracing::debug!(adapter = %self.name, error = %e, "skipped");
                        }
                    }
                }
                self.fill().await?;
            }
        })
        .await;
        answer.unwrap_or_else(|| {
            Err(self.err(ErrorKind::Timeout, format!("no answer to `{text}` within {limit:?}")))
        })
    }
}

#[async_trait]
impl<S: ByteStream> CanBus for SlcanBus<S> {
    async fn send(&mut self, frame: &CanFrame) -> DeviceResult<()> {
        self.out.extend_from_slice(&HostCommand::Transmit(*frame).encode());
        self.flush_out().await?;
        self.status.frames_tx += 1;
        Ok(())
    }

    async fn recv(&mut self) -> DeviceResult<CanFrame> {
        loop {
            if let Some(f) = self.rx.pop_front() {
                return Ok(f);
            }
            while let Some(m) = self.dec.next_message() {
                match m {
                    Ok(AdapterMessage::Received { frame, .. }) => {
                        self.status.frames_rx += 1;
                        return Ok(frame);
                    }
                    Ok(AdapterMessage::Status(f)) => self.note_status(f),
                    Ok(AdapterMessage::Error) => {
                        self.status.adapter_errors += 1;
                        let at = self.bel_offsets.pop_front().unwrap_or(self.fed);
                        tracing::warn!(adapter = %self.name, at, "SLCAN adapter answered BEL");
                    }
                    Ok(_) => {}
                    Err(e) => {
                        self.status.corrupt += 1;
                        return Err(self.err(ErrorKind::Protocol, format!("bad line: {e}")));
                    }
                }
            }
            let now = self.clock.now();
            if let (Some(at), Some(every)) = (self.next_poll, self.options.status_poll) {
                if now >= at {
                    self.out.extend_from_slice(&HostCommand::ReadStatus.encode());
                    self.next_poll = Some(now + every);
                }
            }
            self.flush_out().await?;
            match self.next_poll {
                Some(at) => {
                    let wake = self.clock.sleep_until(at);
                    tokio::select! {
                        r = self.fill() => r?,
                        () = wake => {}
                    }
                }
                None => self.fill().await?,
            }
        }
    }

    fn status(&self) -> BusStatus {
        self.status
    }

    fn describe(&self) -> String {
        format!("slcan {} at {} kbit/s", self.name, self.options.bitrate.bits_per_s() / 1000)
    }

    async fn close(&mut self) -> DeviceResult<()> {
        if !self.open {
            return Ok(());
        }
        self.open = false;
        self.rx.clear();
        self.command(HostCommand::Close, Expect::Ok).await.map(|_| ())
    }
}

impl<S: ByteStream> Drop for SlcanBus<S> {
    fn drop(&mut self) {
        if self.open {
            // Best effort, without waiting: a full port just keeps the channel open.
            let sent = self.stream.write(b"C\r").now_or_never();
            tracing::debug!(adapter = %self.name, ?sent, "SLCAN closed on drop");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::slcan::CanId;
    use crate::SystemClock;
    use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};

    /// Read from the adapter side until `want` has been received.
    async fn expect(adapter: &mut DuplexStream, want: &[u8]) {
        let mut got = vec![0u8; want.len()];
        adapter.read_exact(&mut got).await.expect("read");
        assert_eq!(String::from_utf8_lossy(&got), String::from_utf8_lossy(want));
    }

    async fn open_pair(poll: Option<Duration>) -> (SlcanBus<DuplexStream>, DuplexStream) {
        let (host, mut adapter) = tokio::io::duplex(4096);
        let clock: Arc<dyn Clock> = Arc::new(SystemClock::new(1.0));
        let opts = SlcanOptions { status_poll: poll, ..SlcanOptions::default() };
        let script = async move {
            expect(&mut adapter, b"C\r").await;
            adapter.write_all(&[BEL]).await.expect("w");
            expect(&mut adapter, b"S6\r").await;
            adapter.write_all(b"\r").await.expect("w");
            expect(&mut adapter, b"V\r").await;
            adapter.write_all(b"V1013\r").await.expect("w");
            expect(&mut adapter, b"O\r").await;
            adapter.write_all(b"\r").await.expect("w");
            adapter
        };
        let (bus, adapter) = tokio::join!(SlcanBus::open(host, "duplex", opts, clock), script);
        (bus.expect("opens"), adapter)
    }

    #[tokio::test]
    async fn open_sends_c_s_v_o_and_tolerates_bel_to_c() {
        let (mut bus, mut adapter) = open_pair(None).await;
        assert_eq!(bus.version(), Some((0x10, 0x13)));
        adapter.write_all(b"t1232AABB\rT1234567881122334455667788\r").await.expect("w");
        let f = bus.recv().await.expect("frame");
        assert_eq!(f, CanFrame::new_data(CanId::Standard(0x123), &[0xAA, 0xBB]).expect("f"));
        let f = bus.recv().await.expect("frame");
        assert_eq!(f.id(), CanId::Extended(0x1234_5678));
        assert_eq!(f.data(), &[0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]);
        assert_eq!(bus.status().frames_rx, 2);
    }

    #[tokio::test]
    async fn a_garbled_line_is_one_protocol_error_and_the_next_frame_still_arrives() {
        let (mut bus, mut adapter) = open_pair(None).await;
        adapter.write_all(b"t12x2AABB\rt1231CC\r").await.expect("w");
        let e = bus.recv().await.expect_err("garbled");
        assert_eq!(e.kind(), ErrorKind::Protocol);
        // 9 bytes of open replies (BEL, \r, V1013\r, \r) came first: `x` is stream byte 12.
        assert!(e.message().contains("at byte 12"), "{e}");
        let f = bus.recv().await.expect("next frame");
        assert_eq!(f.data(), &[0xCC]);
        assert_eq!(bus.status().corrupt, 1);
    }

    #[tokio::test]
    async fn bel_to_bitrate_fails_open_with_the_stream_offset() {
        let (host, mut adapter) = tokio::io::duplex(4096);
        let clock: Arc<dyn Clock> = Arc::new(SystemClock::new(1.0));
        let script = async move {
            expect(&mut adapter, b"C\r").await;
            adapter.write_all(b"\r").await.expect("w");
            expect(&mut adapter, b"S6\r").await;
            adapter.write_all(&[BEL]).await.expect("w");
            adapter
        };
        let (bus, _a) =
            tokio::join!(SlcanBus::open(host, "duplex", SlcanOptions::default(), clock), script);
        let e = bus.err().expect("refused");
        assert_eq!(e.kind(), ErrorKind::Protocol);
        assert!(e.message().contains("`S6` at stream byte 1"), "{e}");
    }

    #[tokio::test]
    async fn status_poll_counts_overruns() {
        let (mut bus, mut adapter) = open_pair(Some(Duration::from_millis(1))).await;
        let adapter_task = async move {
            expect(&mut adapter, b"F\r").await;
            adapter.write_all(b"F08\rt1000\r").await.expect("w");
            adapter
        };
        let (f, _a) = tokio::join!(bus.recv(), adapter_task);
        assert_eq!(f.expect("frame").id(), CanId::Standard(0x100));
        assert_eq!(bus.status().overruns, 1);
        assert_eq!(bus.status().flags, slcan::status::OVERRUN);
    }

    #[tokio::test]
    async fn send_writes_the_transmit_command_and_close_sends_c() {
        let (mut bus, mut adapter) = open_pair(None).await;
        let f = CanFrame::new_data(CanId::Standard(0x7FF), &[1, 2]).expect("f");
        bus.send(&f).await.expect("sent");
        expect(&mut adapter, b"t7FF20102\r").await;
        let script = async move {
            adapter.write_all(b"z\r").await.expect("w");
            expect(&mut adapter, b"C\r").await;
            adapter.write_all(b"\r").await.expect("w");
        };
        let (closed, ()) = tokio::join!(bus.close(), script);
        closed.expect("closed");
    }
}
