//! The link of a device reached by request and reply — the rate tables' text lines and the
//! chambers' Modbus registers: one [`RetryPolicy`] for every exchange, settings in seconds, and
//! the [`LineLink`] the table dialects talk through.
//!
//! **Retries.** An exchange that fails for a transient reason ([`ErrorKind::is_transient`]:
//! a timeout, a link fault, an unreadable reply) is tried again, `retries` times at most, after
//! a back-off of `retry_backoff_s` doubled at each further retry (50, 100, 200 ms for 0.05 s).
//! Before each attempt the driver makes its link ready again (reopens what a link fault
//! closed, drains what a timeout left behind). A device's own refusal is never retried.

use std::future::Future;
use std::pin::Pin;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWriteExt};

use crate::protocol::{LineDecoder, LineFormat};
use crate::transport::{BoxStream, Endpoint};
use crate::{DeviceError, ErrorKind};

/// How a device's exchanges are retried (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetryPolicy {
    /// Attempts after the first.
    pub retries: u32,
    /// Wait before the first retry (wall-clock time), doubled for each further one.
    pub backoff: Duration,
}

/// An exchange after its retries: the result of the last attempt and how many were made.
#[derive(Debug)]
pub struct Retried<T, E> {
    /// What the last attempt gave.
    pub result: Result<T, E>,
    /// Attempts made, the first included (at least 1).
    pub attempts: u32,
}

/// One attempt of an exchange on `S`, as a boxed future borrowing it.
pub type Attempt<'a, T, E> = Pin<Box<dyn Future<Output = Result<T, E>> + Send + 'a>>;

impl RetryPolicy {
    /// `retries` retries after a back-off of `backoff_s` seconds (wall-clock), doubling. A
    /// back-off that is not a number of seconds ≥ 0 is none (configs check theirs first).
    pub fn from_seconds(retries: u32, backoff_s: f64) -> Self {
        let backoff = Duration::try_from_secs_f64(backoff_s).unwrap_or(Duration::ZERO);
        Self { retries, backoff }
    }

    /// The wait before retry `retry` (0 for the first): the back-off × 2^retry (the doubling
    /// stops at 2¹⁶).
    pub fn backoff(&self, retry: u32) -> Duration {
        let factor = 2f64.powi(i32::try_from(retry.min(16)).unwrap_or(16));
        Duration::try_from_secs_f64(self.backoff.as_secs_f64() * factor).unwrap_or(Duration::MAX)
    }

    /// Run `attempt` on `state` until it succeeds, fails with a kind that is not transient, or
    /// has been made `retries + 1` times, sleeping [`Self::backoff`] before each retry.
    /// `failed` is told every failure (so the driver can drop or resync its link) and says its
    /// kind. `what` names the exchange in the debug log.
    pub async fn run<S, T, E, A, F>(
        &self,
        state: &mut S,
        what: &str,
        mut attempt: A,
        mut failed: F,
    ) -> Retried<T, E>
    where
        S: Send + ?Sized,
        T: Send,
        E: Send,
        A: for<'a> FnMut(&'a mut S) -> Attempt<'a, T, E> + Send,
        F: FnMut(&mut S, &E) -> ErrorKind + Send,
    {
        let mut attempts = 0;
        loop {
            attempts += 1;
            let e = match attempt(state).await {
                Ok(v) => return Retried { result: Ok(v), attempts },
                Err(e) => e,
            };
            let kind = failed(state, &e);
            if !kind.is_transient() || attempts > self.retries {
                return Retried { result: Err(e), attempts };
            }
            tracing::debug!(what, ?kind, attempt = attempts, "exchange retried");
            tokio::time::sleep(self.backoff(attempts - 1)).await;
        }
    }
}

/// What a line link has had to cope with. Counters only grow.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkCounters {
    /// Replies that could not be decoded (garbled, over-long), skipped.
    pub corrupt_replies: u64,
    /// Well-formed replies that did not answer the command in flight (late answers to an
    /// earlier, timed-out command), skipped.
    pub stale_replies: u64,
    /// Well-formed replies found waiting before a resend and discarded unanswered (late answers
    /// to a timed-out command, drained before the retry).
    pub late_replies: u64,
    /// Exchanges sent again after a transient failure.
    pub retries: u64,
    /// Times the endpoint was reopened after a link fault.
    pub reconnects: u64,
    /// Keep-alive commands sent.
    pub keep_alives: u64,
}

/// Readable form of a request line for messages: no terminator.
pub(crate) fn shown(line: &[u8]) -> String {
    String::from_utf8_lossy(line).trim_end_matches(['\r', '\n']).to_owned()
}

/// A request–reply text link over a serial port or TCP: the stream, the decoder of reply lines in format `F` and
/// what the link has coped with. After a timeout or an unreadable reply the next send first
/// drains what is waiting (late replies); after a link fault the stream is dropped, and the
/// driver reopens it before its next attempt.
pub(crate) struct LineLink<F> {
    /// Where the device is reached.
    pub(crate) endpoint: Endpoint,
    reply_timeout: Duration,
    stream: Option<BoxStream>,
    /// The reply decoder (restarted whenever the stream is).
    pub(crate) decoder: LineDecoder<F>,
    /// Bytes received since the stream was opened.
    rx_total: u64,
    /// `rx_total` when the decoder was last restarted (its offsets count from there).
    rx_base: u64,
    /// Drain stale input before the next send.
    resync: bool,
    /// What the link has coped with.
    pub(crate) counters: LinkCounters,
    /// The exchanges' retry policy.
    pub(crate) policy: RetryPolicy,
}

impl<F: LineFormat> LineLink<F> {
    /// A closed link to `endpoint`.
    pub(crate) fn new(endpoint: Endpoint, reply_timeout: Duration, policy: RetryPolicy) -> Self {
        Self {
            endpoint,
            reply_timeout,
            stream: None,
            decoder: LineDecoder::new(),
            rx_total: 0,
            rx_base: 0,
            resync: false,
            counters: LinkCounters::default(),
            policy,
        }
    }

    /// Whether the stream is open.
    pub(crate) fn is_open(&self) -> bool {
        self.stream.is_some()
    }

    /// Drop the stream (a link fault): the driver reopens it.
    pub(crate) fn close(&mut self) {
        self.stream = None;
    }

    fn reset_decoder(&mut self) {
        self.decoder = LineDecoder::new();
        self.rx_base = self.rx_total;
    }

    /// Open the endpoint (TCP connect timeout: the reply timeout, at least 1 s).
    pub(crate) async fn open(&mut self) -> Result<(), DeviceError> {
        let timeout = self.reply_timeout.max(Duration::from_secs(1));
        let stream = self.endpoint.open(timeout).await?;
        self.stream = Some(stream);
        self.rx_total = 0;
        self.reset_decoder();
        self.resync = false;
        Ok(())
    }

    /// Prepare for the next attempt after `e`; its kind.
    pub(crate) fn note_failure(&mut self, e: &DeviceError) -> ErrorKind {
        match e.kind() {
            ErrorKind::Link => self.stream = None,
            ErrorKind::Timeout | ErrorKind::Protocol => self.resync = true,
            _ => {}
        }
        e.kind()
    }

    /// Discard whatever is already waiting on the link (late replies, counted in
    /// [`LinkCounters::late_replies`] where they decode) and restart the decoder.
    fn drain(&mut self) {
        let mut buf = [0u8; 512];
        let mut closed = false;
        if let Some(s) = self.stream.as_mut() {
            loop {
                let mut cx = std::task::Context::from_waker(std::task::Waker::noop());
                let mut rb = tokio::io::ReadBuf::new(&mut buf);
                match std::pin::Pin::new(&mut *s).poll_read(&mut cx, &mut rb) {
                    std::task::Poll::Ready(Ok(())) if rb.filled().is_empty() => {
                        closed = true;
                        break;
                    }
                    std::task::Poll::Ready(Ok(())) => {
                        self.rx_total = self.rx_total.saturating_add(rb.filled().len() as u64);
                        // The decoder still holds the start of the reply that timed out.
                        self.decoder.push(rb.filled());
                        while let Some(m) = self.decoder.next_message() {
                            self.counters.late_replies += u64::from(m.is_ok());
                        }
                    }
                    std::task::Poll::Ready(Err(_)) => {
                        closed = true;
                        break;
                    }
                    std::task::Poll::Pending => break,
                }
            }
        }
        if closed {
            self.stream = None;
        }
        self.reset_decoder();
    }

    /// Send one request line (draining stale input first when a resync is due).
    pub(crate) async fn send(&mut self, line: &[u8]) -> Result<(), DeviceError> {
        if self.resync {
            self.resync = false;
            self.drain();
        }
        let ep = &self.endpoint;
        let Some(s) = self.stream.as_mut() else {
            return Err(DeviceError::new(ErrorKind::Link, format!("{ep} is not open")));
        };
        let r = async {
            s.write_all(line).await?;
            s.flush().await
        };
        r.await.map_err(|e| {
            DeviceError::new(ErrorKind::Link, format!("sending `{}` on {ep}: {e}", shown(line)))
                .with_source(e)
        })
    }

    /// The deadline of a reply to a request sent now.
    pub(crate) fn deadline(&self) -> tokio::time::Instant {
        tokio::time::Instant::now() + self.reply_timeout
    }

    /// Read more bytes into the decoder before `deadline` (`line` is the request, for
    /// messages).
    pub(crate) async fn fill(
        &mut self,
        line: &[u8],
        deadline: tokio::time::Instant,
    ) -> Result<(), DeviceError> {
        let ep = self.endpoint.to_string();
        let timeout_ms = self.reply_timeout.as_millis();
        let Some(s) = self.stream.as_mut() else {
            return Err(DeviceError::new(ErrorKind::Link, format!("{ep} is not open")));
        };
        let mut buf = [0u8; 512];
        match tokio::time::timeout_at(deadline, s.read(&mut buf)).await {
            Err(_) => Err(DeviceError::new(
                ErrorKind::Timeout,
                format!("sent `{}` on {ep}, no reply within {timeout_ms} ms", shown(line)),
            )),
            Ok(Ok(0)) => Err(DeviceError::new(
                ErrorKind::Link,
                format!("sent `{}` on {ep}, the connection was closed", shown(line)),
            )),
            Ok(Err(e)) => Err(DeviceError::new(
                ErrorKind::Link,
                format!("sent `{}` on {ep}, read failed: {e}", shown(line)),
            )
            .with_source(e)),
            Ok(Ok(n)) => {
                let got = buf.get(..n).unwrap_or_default();
                self.rx_total = self.rx_total.saturating_add(n as u64);
                self.decoder.push(got);
                Ok(())
            }
        }
    }

    /// An unreadable reply to `line`, counted; its offset counts from the stream's opening.
    pub(crate) fn protocol_error(
        &mut self,
        line: &[u8],
        e: crate::protocol::DecodeError,
    ) -> DeviceError {
        self.counters.corrupt_replies += 1;
        let e = e.shifted(self.rx_base);
        tracing::warn!(error = %e, endpoint = %self.endpoint, "unreadable reply skipped");
        DeviceError::new(
            ErrorKind::Protocol,
            format!("sent `{}` on {}, got an unreadable reply: {e}", shown(line), self.endpoint),
        )
        .with_source(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_back_off_doubles_from_its_setting_in_seconds() {
        let p = RetryPolicy::from_seconds(3, 0.05);
        let ms: Vec<u128> = (0..3).map(|k| p.backoff(k).as_millis()).collect();
        assert_eq!(ms, [50, 100, 200]);
        assert_eq!(RetryPolicy::from_seconds(1, f64::NAN).backoff, Duration::ZERO);
        assert!(p.backoff(40) == p.backoff(16), "the doubling stops");
    }

    #[tokio::test(start_paused = true)]
    async fn transient_failures_are_retried_and_refusals_are_not() {
        let p = RetryPolicy::from_seconds(2, 0.01);
        // Fails twice with a timeout, then answers.
        let mut tries = 0u32;
        let r = p
            .run(
                &mut tries,
                "test",
                |n| {
                    Box::pin(async move {
                        *n += 1;
                        if *n < 3 {
                            Err(ErrorKind::Timeout)
                        } else {
                            Ok(*n)
                        }
                    })
                },
                |_, k| *k,
            )
            .await;
        assert_eq!((r.result, r.attempts), (Ok(3), 3));
        // Always a timeout: 1 + 2 attempts, then the last error.
        let r = p
            .run(&mut (), "test", |_| Box::pin(async { Err::<(), _>(ErrorKind::Link) }), |_, k| *k)
            .await;
        assert_eq!((r.result, r.attempts), (Err(ErrorKind::Link), 3));
        // A refusal: once.
        let r = p
            .run(
                &mut (),
                "test",
                |_| Box::pin(async { Err::<(), _>(ErrorKind::OutOfRange) }),
                |_, k| *k,
            )
            .await;
        assert_eq!((r.result, r.attempts), (Err(ErrorKind::OutOfRange), 1));
    }
}
