//! Reader of what `M973` and `M974` print (firmware ≥ 6.3.1), from any [`Read`], streaming
//! and bounded, every capture of a session log in order.
//!
//! The format (M97x.cpp at `v6.3.1`; `docs/accelerometer.md#accelerometer-captures`):
//!
//! ```text
//! 0, 0.01532
//! 1, -0.04597
//! …
//! sampling_freq: 1344.52
//! movement_ok: true
//! accel_error: 0
//! start_marker: 0.20
//! end_marker: 5.87
//! signal_start: 0.43
//! signal_end: 5.43
//! ```
//!
//! Samples are `"%d, %.5f\n"` (lines 492 and 581), indices from 0 without gaps; the seven
//! annotations follow in this order (lines 390–405), with CR LF. Around them a host may add
//! its prefix (`Recv: `), CR, `ok`, `echo:`, `busy:` and temperature lines, and the
//! commands it sent (`Send: M973 …`): those are tolerated, and an echoed `M973`/`M974` is
//! kept as the next capture's [`Gcode`]. Lines that are none of these are skipped between
//! captures and refused inside one. Every error is one line naming the source, the line,
//! the text as written (escaped, cut to [`MAX_SHOWN_CHARS`]) and what was expected.

mod host;

use crate::capture::{AccelCapture, Annotations, Gcode, PlannedTimes};
use host::Line;
use std::io::{BufRead, BufReader, Read};
use stepdamp_out::input::{LineLimited, LineTooLong, printable};

/// The longest line read (bytes, without `\n`): a sample line is under 40 bytes with a host's
/// prefix, a temperature report of a five-tool XL under 300; a longer line (or `/dev/zero`,
/// which has none) is not a capture and is refused after this many bytes.
pub const MAX_LINE_BYTES: usize = 1024;
/// The most samples in one capture: 2²⁰, over 11 minutes at the LIS2DH12's 1344 Hz; the
/// firmware's own calibration moves last seconds.
pub const MAX_SAMPLES: usize = 1 << 20;
/// The most samples in one input (2²², 32 MiB as `f64`): the memory bound of a session log.
pub const MAX_TOTAL_SAMPLES: usize = 1 << 22;
/// The most lines read: twice [`MAX_TOTAL_SAMPLES`], room for a host's chatter; an endless
/// input of short lines is refused after this many (about a second of reading).
pub const MAX_LINES: u64 = 2 * MAX_TOTAL_SAMPLES as u64;
/// The most characters of a line shown in an error.
pub const MAX_SHOWN_CHARS: usize = 60;
/// The most characters of the source's name kept (in messages and [`AccelCapture::source`]).
pub const MAX_NAME_CHARS: usize = 1000;

/// The annotation keys, in the order printed.
const KEYS: [&str; 7] =
    ["sampling_freq", "movement_ok", "accel_error", "start_marker", "end_marker", "signal_start", "signal_end"];

/// Why an input is not a capture log; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReadError {
    /// The input could not be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The source.
        file: String,
        /// The I/O error.
        message: String,
    },
    /// A line is longer than [`MAX_LINE_BYTES`].
    #[error("{file}:{line}: longer than {limit} bytes: not an M973/M974 capture (or an endless input)")]
    LineTooLong {
        /// The source.
        file: String,
        /// The line, 1-based.
        line: u64,
        /// The limit.
        limit: usize,
    },
    /// A line is not what was expected there.
    #[error("{file}:{line}: `{text}`: expected {expected}")]
    Unexpected {
        /// The source.
        file: String,
        /// The line, 1-based.
        line: u64,
        /// The line as written, escaped and cut.
        text: String,
        /// What was expected.
        expected: String,
    },
    /// More lines or samples than the bounds allow.
    #[error("{file}:{line}: more than {limit} {what}: {why}")]
    TooMany {
        /// The source.
        file: String,
        /// The line, 1-based.
        line: u64,
        /// Lines or samples.
        what: &'static str,
        /// The limit.
        limit: u64,
        /// Why the limit.
        why: &'static str,
    },
    /// The input ends inside a capture.
    #[error("{file}:{line}: the input ends inside the capture of line {start}: expected {expected}")]
    Truncated {
        /// The source.
        file: String,
        /// The last line.
        line: u64,
        /// The capture's first line.
        start: u64,
        /// What was still expected.
        expected: String,
    },
    /// No capture at all.
    #[error("{file}: no M973/M974 capture (`<index>, <value>` lines, then `sampling_freq: …` … `signal_end: …`)")]
    Empty {
        /// The source.
        file: String,
    },
}

/// A capture being read.
struct Open {
    start: u64,
    gcode: Option<Gcode>,
    samples: Vec<f64>,
    /// Annotation values read so far (`KEYS` order; booleans as 0/1).
    annotations: Vec<f64>,
}

/// The reader's state between lines.
struct Reader<'a> {
    file: &'a str,
    line: u64,
    pending: Option<Gcode>,
    open: Option<Open>,
    total_samples: usize,
    done: Vec<AccelCapture>,
}

/// The acceleration `M973`/`M974` print per acceleration of the moving motor's belt, from
/// the firmware's `project_to_axis` (calibration.cpp:240–269 at `v6.3.1`).
///
/// - Cartesian (MK4): the sensor's own axis, `1`.
/// - CoreXY (XL, iX): the head's acceleration dotted with `(1, 1)/√2` for X (motor A) and
///   `(−1, 1)/√2` for Y (motor B), unnormalised (`pseudo_project`). One motor alone moves
///   the head by half its belt on each of x and y (`physical_to_logical`, 205–214: A moves
///   `(½, ½)`, B `(½, −½)`), so X prints `+1/√2` and Y `−1/√2` of the belt's acceleration.
/// - The Core One (CoreXY) prints one sensor axis per motor (its y for X, its x for Y):
///   `1/√2` if that axis lies along the motor's diagonal, as the choice suggests; taken with
///   the XL's signs (an **assumption**: its mounting is not in the source).
///
/// Which way the belt moves for a rising phase is the motor's wiring, so the sign is fitted
/// where it matters ([`crate::ripple::RippleOptions::sensor_gain`] takes the size).
pub fn sensor_gain(kinematics: crate::klipper::Kinematics, axis: crate::capture::Axis) -> f64 {
    use crate::capture::Axis;
    use crate::klipper::Kinematics;
    match (kinematics, axis) {
        (Kinematics::Cartesian, _) => 1.0,
        (Kinematics::CoreXy, Axis::X) => std::f64::consts::FRAC_1_SQRT_2,
        (Kinematics::CoreXy, Axis::Y) => -std::f64::consts::FRAC_1_SQRT_2,
    }
}

/// Every capture in `input`, in order; `file` names it in messages and in
/// [`AccelCapture::source`] (escaped: [`stepdamp_out::input::printable`]). Reads line by line: memory stays within [`MAX_LINE_BYTES`] per
/// line and [`MAX_TOTAL_SAMPLES`] samples.
pub fn read_captures<R: Read>(input: R, file: &str) -> Result<Vec<AccelCapture>, ReadError> {
    // A name with control characters (a path is any bytes) is shown escaped, like the text.
    let file = &printable(file.as_bytes(), MAX_NAME_CHARS);
    let mut lines = BufReader::new(LineLimited::new(input, MAX_LINE_BYTES));
    let mut r = Reader { file, line: 0, pending: None, open: None, total_samples: 0, done: Vec::new() };
    let mut buf = Vec::with_capacity(128);
    loop {
        buf.clear();
        let n = lines.read_until(b'\n', &mut buf).map_err(|e| match LineTooLong::from_io(&e) {
            Some(t) => ReadError::LineTooLong { file: file.into(), line: t.line, limit: t.limit },
            None => ReadError::Io { file: file.into(), message: e.to_string() },
        })?;
        if n == 0 {
            break;
        }
        r.line += 1;
        if r.line > MAX_LINES {
            return Err(r.too_many("lines", MAX_LINES, "not a capture log (or an endless input)"));
        }
        let body = buf.strip_suffix(b"\n").unwrap_or(&buf);
        let body = body.strip_suffix(b"\r").unwrap_or(body);
        let text = std::str::from_utf8(body).map_err(|_| r.unexpected(body, "UTF-8 text (a host's log)"))?;
        r.take(text, body)?;
    }
    if let Some(o) = &r.open {
        return Err(ReadError::Truncated { file: file.into(), line: r.line, start: o.start, expected: r.expected() });
    }
    if r.done.is_empty() {
        return Err(ReadError::Empty { file: file.into() });
    }
    Ok(r.done)
}

/// The calibration G-code in `text` (`M973 X F2 R10 H4 A0 B0 C0 D0`, `M974 Y A0.5 B4 R-6`;
/// a line number, checksum and comment are allowed), parsed as the reader parses an echoed
/// command: `None` unless the firmware (≥ 6.3.1) would run it.
pub fn parse_gcode(text: &str) -> Option<Gcode> {
    host::gcode(text)
}

/// [`read_captures`] of the file at `path`.
pub fn read_file(path: &std::path::Path) -> Result<Vec<AccelCapture>, ReadError> {
    let name = path.display().to_string();
    let shown = || printable(name.as_bytes(), MAX_NAME_CHARS);
    let f = std::fs::File::open(path).map_err(|e| ReadError::Io { file: shown(), message: e.to_string() })?;
    read_captures(f, &name)
}

impl Reader<'_> {
    fn unexpected(&self, raw: &[u8], expected: &str) -> ReadError {
        ReadError::Unexpected {
            file: self.file.into(),
            line: self.line,
            text: printable(raw, MAX_SHOWN_CHARS),
            expected: expected.into(),
        }
    }

    fn too_many(&self, what: &'static str, limit: u64, why: &'static str) -> ReadError {
        ReadError::TooMany { file: self.file.into(), line: self.line, what, limit, why }
    }

    /// What the open capture expects next.
    fn expected(&self) -> String {
        match &self.open {
            Some(o) if o.annotations.is_empty() => {
                format!("sample `{}, <value>` or `sampling_freq: <Hz>`", o.samples.len())
            }
            Some(o) => annotation_form(KEYS[o.annotations.len()]),
            None => "a capture".into(),
        }
    }

    /// One line.
    fn take(&mut self, text: &str, raw: &[u8]) -> Result<(), ReadError> {
        let l = match host::classify(text) {
            Line::Blank => return Ok(()),
            Line::Sent(g) => {
                self.pending = g;
                return Ok(());
            }
            Line::Printed(l) => l,
        };
        if host::is_chatter(l) {
            return Ok(());
        }
        if let Some((index, value)) = sample_parts(l) {
            return self.sample(index, value, raw);
        }
        if let Some((key, value)) = l.split_once(':').filter(|(k, _)| KEYS.contains(k)) {
            return self.annotation(key, value.trim(), raw);
        }
        if self.open.is_some() {
            let what = if l.starts_with("Error:") { "the capture's next line, not a firmware error" } else { "" };
            let expected = if what.is_empty() { self.expected() } else { format!("{} ({what})", self.expected()) };
            return Err(self.unexpected(raw, &expected));
        }
        Ok(())
    }

    /// The open capture, opened at this line (with the pending G-code) if none is.
    fn open_capture(&mut self) -> &mut Open {
        let (line, pending) = (self.line, &mut self.pending);
        self.open.get_or_insert_with(|| Open {
            start: line,
            gcode: pending.take(),
            samples: Vec::new(),
            annotations: Vec::new(),
        })
    }

    fn sample(&mut self, index: &str, value: &str, raw: &[u8]) -> Result<(), ReadError> {
        let form = "a sample `<index>, <value>` (`%d, %.5f`)";
        let index: u64 = index.parse().map_err(|_| self.unexpected(raw, form))?;
        let value: f64 =
            value.parse().ok().filter(|v: &f64| v.is_finite()).ok_or_else(|| self.unexpected(raw, form))?;
        if self.open.as_ref().is_some_and(|o| !o.annotations.is_empty()) {
            return Err(self.unexpected(raw, &self.expected()));
        }
        let next = self.open.as_ref().map_or(0, |o| o.samples.len() as u64);
        if index != next {
            let why = if next == 0 {
                "a capture starts at sample 0: its first lines are missing"
            } else {
                "a line was lost or repeated"
            };
            return Err(self.unexpected(raw, &format!("sample {next} ({why})")));
        }
        if next as usize >= MAX_SAMPLES {
            return Err(self.too_many("samples in one capture", MAX_SAMPLES as u64, "over 11 minutes at 1344 Hz"));
        }
        if self.total_samples >= MAX_TOTAL_SAMPLES {
            return Err(self.too_many("samples", MAX_TOTAL_SAMPLES as u64, "the reader's memory bound"));
        }
        self.total_samples += 1;
        let o = self.open_capture();
        o.samples.push(value);
        Ok(())
    }

    fn annotation(&mut self, key: &str, value: &str, raw: &[u8]) -> Result<(), ReadError> {
        let at = self.open.as_ref().map_or(0, |o| o.annotations.len());
        if KEYS[at] != key {
            let expected = if self.open.is_some() { self.expected() } else { "a capture's samples first".into() };
            return Err(self.unexpected(raw, &expected));
        }
        let v = match key {
            "movement_ok" => match value {
                "true" => 1.0,
                "false" => 0.0,
                _ => return Err(self.unexpected(raw, &annotation_form(key))),
            },
            "accel_error" => f64::from(value.parse::<i32>().map_err(|_| self.unexpected(raw, &annotation_form(key)))?),
            _ => {
                let v = value.parse::<f64>().ok().filter(|v| v.is_finite() && *v >= 0.0);
                v.ok_or_else(|| self.unexpected(raw, &annotation_form(key)))?
            }
        };
        let o = self.open_capture();
        o.annotations.push(v);
        if o.annotations.len() == KEYS.len() {
            let o = self.open.take().expect("open above");
            self.done.push(finish(o, self.file));
        }
        Ok(())
    }
}

/// `(index, value)` of a line shaped like a sample: digits, `,`, the rest.
fn sample_parts(l: &str) -> Option<(&str, &str)> {
    let (i, v) = l.split_once(',')?;
    (!i.is_empty() && i.bytes().all(|b| b.is_ascii_digit())).then_some((i, v.trim()))
}

/// How an annotation is printed.
fn annotation_form(key: &str) -> String {
    let v = match key {
        "movement_ok" => "true|false",
        "accel_error" => "<integer>",
        "sampling_freq" => "<Hz ≥ 0>",
        _ => "<s ≥ 0>",
    };
    format!("`{key}: {v}`")
}

fn finish(o: Open, file: &str) -> AccelCapture {
    let a = &o.annotations;
    let annotations = Annotations {
        sampling_freq_hz: a[0],
        movement_ok: a[1] == 1.0,
        accel_error: a[2] as i64,
        times: PlannedTimes { start_marker: a[3], end_marker: a[4], signal_start: a[5], signal_end: a[6] },
    };
    AccelCapture { source: file.into(), line: o.start, gcode: o.gcode, samples: o.samples, annotations }
}

#[cfg(test)]
mod tests;
