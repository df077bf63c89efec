//! Device errors, classified by kind so the orchestrator decides retry vs abort whatever the
//! transport.

use std::fmt;

/// What went wrong, independent of the transport. The orchestrator retries `Timeout`, `Link`
/// and `Protocol` (within limits) and aborts to a safe state on the rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ErrorKind {
    /// No reply within the allowed time.
    Timeout,
    /// The device is not ready for the command (not in remote mode, not initialised).
    NotReady,
    /// A command argument is outside the device's capability.
    OutOfRange,
    /// A safety interlock is open (door, drive alarm, over-temperature cut-out).
    InterlockTripped,
    /// The link failed: port closed, connection reset, framing lost.
    Link,
    /// A reply was received but could not be understood (bad CRC, malformed frame).
    Protocol,
    /// The device reports a fault of its own (drive alarm, sensor break).
    DeviceFault,
    /// The device does not support this operation.
    Unsupported,
    /// Anything else.
    Other,
}

impl ErrorKind {
    /// Whether a retry of the same operation may succeed (a link fault, not a device fault).
    pub fn is_transient(self) -> bool {
        matches!(self, ErrorKind::Timeout | ErrorKind::Link | ErrorKind::Protocol)
    }
}

impl fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            ErrorKind::Timeout => "timeout",
            ErrorKind::NotReady => "not ready",
            ErrorKind::OutOfRange => "out of range",
            ErrorKind::InterlockTripped => "interlock tripped",
            ErrorKind::Link => "link error",
            ErrorKind::Protocol => "protocol error",
            ErrorKind::DeviceFault => "device fault",
            ErrorKind::Unsupported => "unsupported",
            ErrorKind::Other => "error",
        };
        f.write_str(s)
    }
}

/// An error from a device: a kind, a message saying what was tried and what came back, and the
/// underlying cause where there is one.
#[derive(Debug, thiserror::Error)]
#[error("{kind}: {message}")]
pub struct DeviceError {
    kind: ErrorKind,
    message: String,
    #[source]
    source: Option<Box<dyn std::error::Error + Send + Sync + 'static>>,
}

impl DeviceError {
    /// A new error of `kind` with a message.
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Self { kind, message: message.into(), source: None }
    }

    /// Attach the underlying cause.
    pub fn with_source(mut self, source: impl std::error::Error + Send + Sync + 'static) -> Self {
        self.source = Some(Box::new(source));
        self
    }

    /// The kind of error.
    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    /// The message, without the kind.
    pub fn message(&self) -> &str {
        &self.message
    }

    /// `Unsupported` error for an optional operation.
    pub fn unsupported(what: &str) -> Self {
        Self::new(ErrorKind::Unsupported, format!("{what} is not supported by this device"))
    }
}

impl From<std::io::Error> for DeviceError {
    fn from(e: std::io::Error) -> Self {
        let kind = match e.kind() {
            std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock => ErrorKind::Timeout,
            _ => ErrorKind::Link,
        };
        DeviceError::new(kind, e.to_string()).with_source(e)
    }
}

/// Result alias for device operations.
pub type DeviceResult<T> = Result<T, DeviceError>;
