//! `data_logger.py`'s `LogWriter` (data_logger.py:54–76): one gzip stream, every message
//! followed by `0x03`, a full flush at each index point (its compressed offset is what the
//! index records) and the gzip trailer at the end.

use flate2::{Compress, Compression, Crc, FlushCompress};

/// The separator after every message (data_logger.py:61).
const SEPARATOR: u8 = 0x03;

/// A gzip stream being written.
pub(crate) struct GzLog {
    out: Vec<u8>,
    comp: Compress,
    crc: Crc,
}

impl GzLog {
    /// The gzip header (no name, no time; OS 3, as Python's `zlib` writes it).
    pub(crate) fn new() -> Self {
        let out = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3];
        GzLog { out, comp: Compress::new(Compression::default(), false), crc: Crc::new() }
    }

    fn deflate(&mut self, input: &[u8], flush: FlushCompress) {
        let mut done = 0;
        loop {
            self.out.reserve(input.len() - done + 1024);
            let before = self.comp.total_in();
            let status = self.comp.compress_vec(&input[done..], &mut self.out, flush).expect("deflate into a Vec");
            done += (self.comp.total_in() - before) as usize;
            let full = self.out.len() < self.out.capacity();
            let finished = match flush {
                FlushCompress::Finish => status == flate2::Status::StreamEnd,
                _ => done == input.len() && full,
            };
            if finished {
                return;
            }
        }
    }

    /// One message and its separator (`add_data`, data_logger.py:60–64).
    pub(crate) fn add(&mut self, message: &str) {
        let mut m = Vec::with_capacity(message.len() + 1);
        m.extend_from_slice(message.as_bytes());
        m.push(SEPARATOR);
        self.crc.update(&m);
        self.deflate(&m, FlushCompress::None);
    }

    /// A full flush; the compressed size so far (`flush`, data_logger.py:65–71).
    pub(crate) fn flush(&mut self) -> usize {
        self.deflate(&[], FlushCompress::Full);
        self.out.len()
    }

    /// The finished stream (`close`, data_logger.py:72–76).
    pub(crate) fn finish(mut self) -> Vec<u8> {
        self.deflate(&[], FlushCompress::Finish);
        let (crc, len) = (self.crc.sum(), self.crc.amount());
        self.out.extend_from_slice(&crc.to_le_bytes());
        self.out.extend_from_slice(&len.to_le_bytes());
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    #[test]
    fn the_stream_inflates_to_the_messages_and_a_flush_point_starts_a_raw_inflate() {
        let mut g = GzLog::new();
        g.add("{\"a\":1}");
        let at = g.flush();
        g.add("{\"b\":2}");
        let bytes = g.finish();
        let mut text = String::new();
        flate2::read::GzDecoder::new(bytes.as_slice()).read_to_string(&mut text).unwrap();
        assert_eq!(text, "{\"a\":1}\u{3}{\"b\":2}\u{3}");
        // readlog.py:629–631 seeks to a flush point and inflates raw from there.
        let mut rest = Vec::new();
        flate2::read::DeflateDecoder::new(&bytes[at..bytes.len() - 8]).read_to_end(&mut rest).unwrap();
        assert_eq!(rest, b"{\"b\":2}\x03");
    }
}
