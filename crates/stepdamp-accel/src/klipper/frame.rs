//! The framing of a motion-analysis log: one gzip stream (`zlib` with `wbits = 31`,
//! data_logger.py:57–58) of JSON messages, each followed by the byte `0x03`
//! (data_logger.py:61), read record by record within the caps of [`super`].

use super::{KlipperError, MAX_DECOMPRESSED_BYTES, MAX_RECORD_BYTES};
use flate2::read::GzDecoder;
use std::io::{BufRead, BufReader, ErrorKind, Read};

/// The message separator the logger writes after every message (data_logger.py:61).
pub(crate) const SEPARATOR: u8 = 0x03;

/// A reader that fails once more than `limit` bytes came through: the decompressed size cap.
struct Capped<R> {
    inner: R,
    seen: u64,
    limit: u64,
}

impl<R: Read> Read for Capped<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.seen += n as u64;
        if self.seen > self.limit {
            return Err(std::io::Error::other(TooLarge));
        }
        Ok(n)
    }
}

/// The marker of [`Capped`]'s error.
#[derive(Debug)]
struct TooLarge;

impl std::fmt::Display for TooLarge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("decompressed size cap")
    }
}

impl std::error::Error for TooLarge {}

/// The records of one log, in order.
pub(crate) struct Records<'a, R: Read> {
    file: &'a str,
    inner: BufReader<Capped<GzDecoder<R>>>,
    /// The records returned so far (the last one's 1-based number).
    record: u64,
    buf: Vec<u8>,
}

impl<'a, R: Read> Records<'a, R> {
    pub(crate) fn new(input: R, file: &'a str) -> Self {
        let capped = Capped { inner: GzDecoder::new(input), seen: 0, limit: MAX_DECOMPRESSED_BYTES };
        Records { file, inner: BufReader::with_capacity(1 << 16, capped), record: 0, buf: Vec::new() }
    }

    fn error(&self, e: &std::io::Error) -> KlipperError {
        let file = self.file.to_string();
        let offset = self.inner.get_ref().seen;
        if e.get_ref().is_some_and(|x| x.is::<TooLarge>()) {
            return KlipperError::TooMany {
                file,
                record: self.record + 1,
                what: "decompressed bytes",
                limit: MAX_DECOMPRESSED_BYTES,
                why: "the reader's bound (a zip bomb, or over an hour of logging)",
            };
        }
        let why = if e.kind() == ErrorKind::UnexpectedEof {
            "the gzip stream is cut (the logger did not close it: stop data_logger.py with Ctrl-C)".to_string()
        } else {
            format!("not a gzip stream as data_logger.py writes it: {e}")
        };
        KlipperError::Gzip { file, offset, message: why }
    }

    /// The next record without its separator, or `None` at the end of the stream.
    pub(crate) fn next_record(&mut self) -> Result<Option<&[u8]>, KlipperError> {
        self.buf.clear();
        loop {
            let chunk = match self.inner.fill_buf() {
                Ok(c) => c,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(self.error(&e)),
            };
            if chunk.is_empty() {
                if self.buf.is_empty() {
                    return Ok(None);
                }
                return Err(KlipperError::Record {
                    file: self.file.into(),
                    record: self.record + 1,
                    key: "(framing)".into(),
                    value: stepdamp_out::input::printable(&self.buf, super::MAX_SHOWN_CHARS),
                    expected: "a message ended by 0x03, as data_logger.py writes every message".into(),
                });
            }
            let (take, done) = match chunk.iter().position(|&b| b == SEPARATOR) {
                Some(i) => (i, true),
                None => (chunk.len(), false),
            };
            if self.buf.len() + take > MAX_RECORD_BYTES {
                return Err(KlipperError::TooMany {
                    file: self.file.into(),
                    record: self.record + 1,
                    what: "bytes in one message",
                    limit: MAX_RECORD_BYTES as u64,
                    why: "a batch of the logger is tens of kB",
                });
            }
            self.buf.extend_from_slice(&chunk[..take]);
            self.inner.consume(take + usize::from(done));
            if done {
                self.record += 1;
                return Ok(Some(&self.buf));
            }
        }
    }
}
