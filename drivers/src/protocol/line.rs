//! Line protocols: a byte stream split into terminated lines, each line's stream offset kept, and
//! [`LineDecoder`], the one incremental decoder of every protocol whose messages are lines (a
//! protocol says only how its lines end and parse: [`LineFormat`]).

use std::fmt;
use std::marker::PhantomData;

use super::DecodeError;

/// One direction of a line protocol: what ends its lines, how long they may be, which lines carry
/// nothing, and how a line parses.
pub trait LineFormat {
    /// What one line decodes to.
    type Message;
    /// Bytes that end a line (a `\r` before a `\n` terminator is dropped too).
    const TERMINATORS: &'static [u8] = b"\n";
    /// Longest line accepted, bytes; a longer one is an error and is skipped.
    const MAX_LINE: usize;
    /// Parses one line (terminator removed); error offsets count from the line's start.
    fn parse(line: &[u8]) -> Result<Self::Message, DecodeError>;
    /// Whether a line carries no message and is skipped (default: blank, only whitespace).
    fn is_filler(line: &[u8]) -> bool {
        line.iter().all(u8::is_ascii_whitespace)
    }
}

/// Incremental decoder of a line protocol: feed bytes as they arrive ([`push`](Self::push)),
/// take messages out ([`next_message`](Self::next_message)). A line that does not parse
/// (including a partial line at the start of a connection) is an error with its stream offset,
/// and decoding carries on with the next line.
pub struct LineDecoder<F> {
    lines: LineSplitter,
    format: PhantomData<fn() -> F>,
}

impl<F: LineFormat> LineDecoder<F> {
    /// A decoder at stream offset 0.
    pub fn new() -> Self {
        Self { lines: LineSplitter::new(F::TERMINATORS, F::MAX_LINE), format: PhantomData }
    }

    /// Feeds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.lines.push(bytes);
    }

    /// The next message, an error for a line that is not one, or `None` until a line is
    /// complete.
    pub fn next_message(&mut self) -> Option<Result<F::Message, DecodeError>> {
        loop {
            let line = match self.lines.next_line()? {
                Ok(l) => l,
                Err(e) => return Some(Err(e)),
            };
            if F::is_filler(&line.bytes) {
                continue;
            }
            return Some(F::parse(&line.bytes).map_err(|e| e.shifted(line.offset)));
        }
    }
}

impl<F: LineFormat> Default for LineDecoder<F> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F> Clone for LineDecoder<F> {
    fn clone(&self) -> Self {
        Self { lines: self.lines.clone(), format: PhantomData }
    }
}

impl<F> fmt::Debug for LineDecoder<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LineDecoder").field("lines", &self.lines).finish()
    }
}

/// One complete line, without its terminator.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Line {
    /// Stream offset of the line's first byte.
    pub offset: u64,
    /// The line's bytes (terminator removed, and a `\r` before a `\n` terminator too).
    pub bytes: Vec<u8>,
    /// The terminator byte that ended the line.
    pub terminator: u8,
}

/// Incremental line splitter with a maximum line length.
#[derive(Debug, Clone)]
pub(crate) struct LineSplitter {
    buf: Vec<u8>,
    /// Stream offset of `buf[0]`.
    base: u64,
    terminators: &'static [u8],
    max_len: usize,
    /// Discarding an over-long line until the next terminator.
    discarding: bool,
}

impl LineSplitter {
    pub(crate) fn new(terminators: &'static [u8], max_len: usize) -> Self {
        Self { buf: Vec::new(), base: 0, terminators, max_len, discarding: false }
    }

    pub(crate) fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    fn take(&mut self, n: usize) -> Vec<u8> {
        let n = n.min(self.buf.len());
        let rest = self.buf.split_off(n);
        let head = std::mem::replace(&mut self.buf, rest);
        self.base = self.base.saturating_add(n as u64);
        head
    }

    fn overlong_error(&self) -> DecodeError {
        DecodeError::new(self.base, format!("a line of at most {} bytes", self.max_len), &self.buf)
    }

    /// The next complete line, an error for an over-long line, or `None` when more bytes are
    /// needed.
    pub(crate) fn next_line(&mut self) -> Option<Result<Line, DecodeError>> {
        loop {
            let end = self.buf.iter().position(|b| self.terminators.contains(b));
            if self.discarding {
                match end {
                    Some(i) => {
                        self.take(i.saturating_add(1));
                        self.discarding = false;
                        continue;
                    }
                    None => {
                        let n = self.buf.len();
                        self.take(n);
                        return None;
                    }
                }
            }
            return match end {
                Some(i) if i <= self.max_len => {
                    let offset = self.base;
                    let mut bytes = self.take(i.saturating_add(1));
                    let terminator = bytes.pop().unwrap_or_default();
                    if terminator == b'\n' && bytes.last() == Some(&b'\r') {
                        bytes.pop();
                    }
                    Some(Ok(Line { offset, bytes, terminator }))
                }
                Some(i) => {
                    let err = self.overlong_error();
                    self.take(i.saturating_add(1));
                    Some(Err(err))
                }
                None if self.buf.len() > self.max_len => {
                    let err = self.overlong_error();
                    let n = self.buf.len();
                    self.take(n);
                    self.discarding = true;
                    Some(Err(err))
                }
                None => None,
            };
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn splits_with_offsets_and_strips_cr() {
        let mut s = LineSplitter::new(b"\n", 16);
        s.push(b"ab\r\ncd");
        let l = s.next_line().unwrap().unwrap();
        assert_eq!((l.offset, l.bytes.as_slice()), (0, &b"ab"[..]));
        assert!(s.next_line().is_none());
        s.push(b"\n");
        let l = s.next_line().unwrap().unwrap();
        assert_eq!((l.offset, l.bytes.as_slice()), (4, &b"cd"[..]));
    }

    #[test]
    fn overlong_line_is_reported_then_skipped() {
        let mut s = LineSplitter::new(b"\n", 4);
        s.push(b"0123456");
        let e = s.next_line().unwrap().unwrap_err();
        assert_eq!(e.offset, 0);
        s.push(b"89\nok\n");
        let l = s.next_line().unwrap().unwrap();
        assert_eq!((l.offset, l.bytes.as_slice()), (10, &b"ok"[..]));
    }
}
