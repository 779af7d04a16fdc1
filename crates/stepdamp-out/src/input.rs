//! Bounded input: a file read whole only up to a byte limit, a reader that refuses a line
//! longer than a limit, and text made safe to print.
//!
//! Why: `/dev/zero`, a 2 GB file of zeros or a file that is not what was expected must be
//! refused within seconds and a few MB of memory, not read to the end; and bytes from a file
//! must not reach a terminal as control sequences.

use std::io::{self, Read};
use std::path::Path;

/// Reads a whole file of at most `max_bytes` bytes into memory, in one pass (so a FIFO or
/// a device is read once, never measured first). A longer input (or an endless one like
/// `/dev/zero`) is refused after reading `max_bytes + 1` bytes, with an
/// [`io::ErrorKind::InvalidData`] error saying the limit; memory stays below
/// `max_bytes + 1` plus the buffer's growth. Every file argument read whole goes through
/// here (or [`read_to_string_bounded`]); the caller's kind of file defines `max_bytes` with
/// its reason (docs/files.md#size-limits).
pub fn read_bounded(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let f = std::fs::File::open(path)?;
    let mut buf = Vec::new();
    f.take(max_bytes + 1).read_to_end(&mut buf)?;
    if buf.len() as u64 > max_bytes {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("larger than {max_bytes} bytes: not a file of this kind (or an endless input)"),
        ));
    }
    Ok(buf)
}

/// Reads a whole text file of at most `max_bytes` bytes (profiles, study specs) with
/// [`read_bounded`]; text that is not UTF-8 is refused with an
/// [`io::ErrorKind::InvalidData`] error naming the first bad byte.
pub fn read_to_string_bounded(path: &Path, max_bytes: u64) -> io::Result<String> {
    let buf = read_bounded(path, max_bytes)?;
    String::from_utf8(buf).map_err(|e| {
        io::Error::new(io::ErrorKind::InvalidData, format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()))
    })
}

/// A line longer than the limit was read (see [`LineLimited`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineTooLong {
    /// The line, 1-based.
    pub line: u64,
    /// The limit in bytes.
    pub limit: usize,
}

impl std::fmt::Display for LineTooLong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {} is longer than {} bytes", self.line, self.limit)
    }
}

impl std::error::Error for LineTooLong {}

impl LineTooLong {
    /// The [`LineTooLong`] inside an I/O error, if that is what it is.
    pub fn from_io(e: &io::Error) -> Option<LineTooLong> {
        e.get_ref().and_then(|r| r.downcast_ref::<LineTooLong>()).copied()
    }
}

/// A reader that fails with [`LineTooLong`] (inside an [`io::ErrorKind::InvalidData`]
/// error) as soon as a line exceeds `limit` bytes, so a parser above it never buffers more
/// than that for one line. Cost: one `memchr`-like scan of the bytes read.
#[derive(Debug)]
pub struct LineLimited<R> {
    inner: R,
    limit: usize,
    /// Bytes of the current line read so far.
    current: usize,
    /// The current line, 1-based.
    line: u64,
}

impl<R: Read> LineLimited<R> {
    /// Wraps `inner`; lines (without their `\n`) may be at most `limit` bytes.
    pub fn new(inner: R, limit: usize) -> Self {
        LineLimited { inner, limit, current: 0, line: 1 }
    }
}

impl<R: Read> Read for LineLimited<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        for &b in &buf[..n] {
            if b == b'\n' {
                self.line += 1;
                self.current = 0;
            } else {
                self.current += 1;
                if self.current > self.limit {
                    let e = LineTooLong { line: self.line, limit: self.limit };
                    return Err(io::Error::new(io::ErrorKind::InvalidData, e));
                }
            }
        }
        Ok(n)
    }
}

/// `bytes` as text safe to print: invalid UTF-8 as `\u{fffd}`, control characters
/// (including escape sequences' `ESC`) escaped as `\u{1b}`-style, at most `max_chars`
/// characters (then `…`).
pub fn printable(bytes: &[u8], max_chars: usize) -> String {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::new();
    for (i, c) in text.chars().enumerate() {
        if i == max_chars {
            out.push('…');
            break;
        }
        if c.is_control() || c == '\u{feff}' {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    out
}

/// Why a CSV file is visibly not in the dialect stepdamp reads (`,` between columns, `.` as
/// the decimal mark), judged from its header line and, if there is one, its first data
/// line; `None` when it looks right. A spreadsheet in a locale with a decimal comma
/// exports `;`-separated columns and `1,5`; read as stepdamp's CSV, such a header is one
/// column named after the whole line, and a reader would say "missing column" while
/// quoting the very name it asks for. Readers add this to that message.
pub fn csv_dialect_problem(header: &str, first_row: Option<&str>) -> Option<String> {
    const WANT: &str = "stepdamp reads `,` between columns and `.` as the decimal mark";
    let fields = |line: &str| line.split(',').count();
    if !header.contains(',') {
        for (sep, name) in [(';', "`;`"), ('\t', "tabs")] {
            if header.contains(sep) {
                let decimal = first_row.is_some_and(|r| r.contains(','));
                let also = if decimal { " and `,` as the decimal mark" } else { "" };
                return Some(format!("the file separates columns with {name}{also}: {WANT}"));
            }
        }
    }
    let row = first_row?;
    // A decimal comma in a comma-separated file: more fields than the header has names,
    // with a digit on both sides of an extra comma.
    let digit_comma_digit =
        row.as_bytes().windows(3).any(|w| w[0].is_ascii_digit() && w[1] == b',' && w[2].is_ascii_digit());
    if fields(row) > fields(header) && digit_comma_digit {
        return Some(format!(
            "line 2 has {} fields for {} columns: the file seems to use `,` as the decimal mark; {WANT}",
            fields(row),
            fields(header)
        ));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_input_is_refused_after_the_limit() {
        let e = read_to_string_bounded(Path::new("/dev/zero"), 1000).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        assert!(e.to_string().contains("larger than 1000 bytes"), "{e}");
    }

    #[test]
    fn a_fifo_is_read_once_to_its_end_or_refused_at_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&p).status().is_ok_and(|s| s.success());
        if !made {
            return; // no mkfifo on this system: nothing to prove
        }
        let writer = {
            let p = p.clone();
            // A broken pipe, if the reader stops first, is what a refused FIFO does to its writer.
            std::thread::spawn(move || drop(std::fs::write(&p, vec![b'x'; 5000])))
        };
        let e = read_bounded(&p, 4096).unwrap_err();
        assert!(e.to_string().contains("larger than 4096 bytes"), "{e}");
        writer.join().unwrap();
        let p2 = dir.path().join("fifo2");
        assert!(std::process::Command::new("mkfifo").arg(&p2).status().unwrap().success());
        let writer = {
            let p2 = p2.clone();
            std::thread::spawn(move || std::fs::write(&p2, b"abc").unwrap())
        };
        assert_eq!(read_bounded(&p2, 4096).unwrap(), b"abc");
        writer.join().unwrap();
    }

    #[test]
    fn a_file_within_the_limit_is_read_and_non_utf8_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.toml");
        std::fs::write(&p, "name = \"x\"\n").unwrap();
        assert_eq!(read_to_string_bounded(&p, 11).unwrap(), "name = \"x\"\n");
        assert!(read_to_string_bounded(&p, 10).is_err());
        std::fs::write(&p, b"ab\xff").unwrap();
        assert!(read_to_string_bounded(&p, 10).unwrap_err().to_string().contains("byte 2"));
    }

    #[test]
    fn a_long_line_is_refused_with_its_line_number() {
        let text = format!("short\n{}\n", "x".repeat(100));
        let mut r = LineLimited::new(text.as_bytes(), 50);
        let mut sink = Vec::new();
        let e = r.read_to_end(&mut sink).unwrap_err();
        assert_eq!(LineTooLong::from_io(&e), Some(LineTooLong { line: 2, limit: 50 }));
        let mut ok = LineLimited::new("a\nbb\n".as_bytes(), 2);
        sink.clear();
        ok.read_to_end(&mut sink).unwrap();
        assert_eq!(sink, b"a\nbb\n");
    }

    #[test]
    fn a_semicolon_or_decimal_comma_csv_is_named_as_such() {
        let e = csv_dialect_problem("t_s;theta_cmd_rad;i_a_a", Some("0,00005;0,1;1,9")).unwrap();
        assert!(e.contains("`;`") && e.contains("decimal mark") && e.contains("stepdamp reads"), "{e}");
        let e = csv_dialect_problem("t_s;theta_cmd_rad", Some("0.5;0.1")).unwrap();
        assert!(e.contains("`;`") && !e.contains("and `,` as the decimal mark"), "{e}");
        assert!(csv_dialect_problem("t_s\ti_a_a", None).unwrap().contains("tabs"));
        let e = csv_dialect_problem("t_s,i_a_a", Some("0,5,1,9")).unwrap();
        assert!(e.contains("4 fields for 2 columns"), "{e}");
    }

    #[test]
    fn a_proper_csv_has_no_dialect_problem() {
        assert_eq!(csv_dialect_problem("t_s,i_a_a", Some("0.5,1.9")), None);
        assert_eq!(csv_dialect_problem("t_s,i_a_a", None), None);
        assert_eq!(csv_dialect_problem("t_s", Some("0.5")), None);
        assert_eq!(csv_dialect_problem("name,comment", Some("a,\"b;c\"")), None);
    }

    #[test]
    fn control_bytes_are_escaped_and_long_text_is_cut() {
        assert_eq!(printable(b"a\x1b[31mb\x00", 100), "a\\u{1b}[31mb\\u{0}");
        assert_eq!(printable(b"\xff\xfe", 100), "\u{fffd}\u{fffd}");
        assert_eq!(printable(b"abcdef", 3), "abc…");
    }
}
