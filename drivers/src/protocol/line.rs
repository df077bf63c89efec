//! Splits a byte stream into terminated lines, keeping each line's stream offset.

use super::DecodeError;

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

    /// The next line that is not blank (only whitespace), parsed by `parse` with its errors
    /// shifted to stream offsets; an over-long line is an error; `None` when more bytes are
    /// needed.
    pub(crate) fn next_parsed<T>(
        &mut self,
        parse: impl Fn(&[u8]) -> Result<T, DecodeError>,
    ) -> Option<Result<T, DecodeError>> {
        loop {
            let line = match self.next_line()? {
                Ok(l) => l,
                Err(e) => return Some(Err(e)),
            };
            if line.bytes.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            return Some(parse(&line.bytes).map_err(|e| e.shifted(line.offset)));
        }
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
