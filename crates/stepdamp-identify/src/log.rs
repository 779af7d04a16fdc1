//! Run logs (docs/files.md, "Run log"): CSV with a header row, one row per control period, read into
//! the few columns identification needs.
//!
//! # Columns
//!
//! | column | unit | needed |
//! |---|---|---|
//! | `t_s` | s | **yes**: strictly increasing |
//! | `theta_fb_rad` | rad, mechanical | **yes**: the encoder angle (ideally the centre of the count interval) |
//! | `i_q_a` | A | **yes**, or both `i_a_a` and `i_b_a` |
//! | `i_a_a`, `i_b_a` | A | instead of `i_q_a`: then `i_q = −i_a sin θe + i_b cos θe` at `θe = Nr·θ_fb` |
//! | `iq_cmd_a` | A | optional: the loop's q-current command (an alternative measure of loop effort) |
//! | `theta_cmd_rad`, `omega_fb_rad_s`, `i_d_a` | | read when present, not needed |
//!
//! Columns may come in any order. Unknown columns are ignored and listed in
//! [`RunLog::ignored_columns`] so the caller can say so.
//!
//! `i_q_a` must be the measured torque current in the encoder's frame (what a servo drive
//! logs); the torque it makes is `Km·i_q`. Every number must parse as a finite `f64`.
//!
//! # Errors
//!
//! Every [`LogError`] names the file, and where it applies the line (1 = the header) and
//! the column: a missing column, an unparseable or non-finite value, a time that does not
//! increase, a log that covers too few electrical periods, a line longer than
//! [`MAX_LINE_BYTES`], a header wider than [`MAX_COLUMNS`]. Text from the file is shown
//! with control characters escaped and cut to [`SHOWN_CHARS`] characters (at most
//! [`SHOWN_COLUMNS`] column names), so a binary file never reaches the terminal raw.
//!
//! # Cost
//!
//! One streaming pass over the bytes with the `csv` crate (no quoting: a log is numbers),
//! parsing only the needed columns into `f64` vectors as the rows come: memory is 8 bytes
//! per kept value (×2 at most while a vector grows) plus one line, never the text. About
//! 0.5 µs per row of the §6 log in a release build (200 000 rows in ≈ 0.1 s). Input that is
//! not a log (`/dev/zero`, a file of zeros) is refused after at most [`MAX_LINE_BYTES`].

use std::io::Read;
use std::path::Path;
use stepdamp_out::input::{LineLimited, LineTooLong, printable};
use stepdamp_profile::LogRow;

/// The columns a run log must or may carry (docs/files.md, "Run log").
pub const KNOWN_COLUMNS: [&str; 9] =
    ["t_s", "theta_cmd_rad", "theta_fb_rad", "omega_fb_rad_s", "i_a_a", "i_b_a", "i_d_a", "i_q_a", "iq_cmd_a"];

/// Longest line accepted, in bytes. A §6 row is about 200 bytes and a header of
/// [`MAX_COLUMNS`] 60-character names 60 KiB; anything longer is not a run log, and the
/// bound keeps one line's buffer small whatever the input.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Largest `|θ_fb|` accepted, rad (160 million revolutions: days of logging at 1000 rad/s).
/// Beyond it `sin(k·Nr·θ)` loses its meaning in `f64` (the spacing of `f64` near
/// `Nr·θ = 5·10¹⁰` is 8·10⁻⁶ rad, and grows with θ) and the Park transform overflows to NaN.
pub const MAX_ANGLE_RAD: f64 = 1e9;

/// Most columns a header may have (the §6 log has 9; tools add a few dozen at most).
pub const MAX_COLUMNS: usize = 1024;

/// Most characters of one text from the file (a value, a column name) quoted in a message.
pub const SHOWN_CHARS: usize = 40;

/// Most column names listed in a message.
pub const SHOWN_COLUMNS: usize = 20;

/// Fewest electrical periods a log must cover by default (a harmonic fit needs whole periods;
/// fewer than two cannot separate the first harmonic from a drift).
pub const DEFAULT_MIN_ELECTRICAL_PERIODS: f64 = 2.0;

/// Where `i_q` came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IqSource {
    /// The `i_q_a` column.
    Column,
    /// Park of `i_a_a`, `i_b_a` at `Nr·θ_fb`.
    Park,
}

/// A run log, reduced to what identification uses. All vectors have the same length.
#[derive(Clone, Debug, PartialEq)]
pub struct RunLog {
    /// Name of the source (the file path), used in messages.
    pub source: String,
    /// Time in s, strictly increasing.
    pub t_s: Vec<f64>,
    /// Encoder angle `θ_fb` in rad (mechanical).
    pub theta_fb_rad: Vec<f64>,
    /// Measured torque current `i_q` in A (encoder frame).
    pub i_q_a: Vec<f64>,
    /// The loop's q-current command in A, when logged.
    pub iq_cmd_a: Option<Vec<f64>>,
    /// Where `i_q` came from.
    pub iq_source: IqSource,
    /// Header columns that were not used (unknown names), in file order.
    pub ignored_columns: Vec<String>,
}

/// Options of log reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogOptions {
    /// Rotor pole pairs `Nr` (to Park `i_a`, `i_b` and count electrical periods).
    pub pole_pairs: u16,
    /// Fewest electrical periods (`Nr·|θ_end − θ_start| / 2π`) the log must cover.
    pub min_electrical_periods: f64,
}

impl LogOptions {
    /// Defaults for a motor with `pole_pairs` pole pairs.
    pub fn new(pole_pairs: u16) -> Self {
        LogOptions { pole_pairs, min_electrical_periods: DEFAULT_MIN_ELECTRICAL_PERIODS }
    }
}

/// Why a log could not be read. Each message names the file and, where it applies, the
/// line (the header is line 1) and the column.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file has no header row or no data rows.
    #[error("{path}: {what}")]
    Empty {
        /// The file.
        path: String,
        /// What is missing.
        what: &'static str,
    },
    /// A needed column is not in the header.
    #[error("{path}: line 1 (header): missing column '{column}' ({need}); the header has: {found}")]
    MissingColumn {
        /// The file.
        path: String,
        /// The column.
        column: &'static str,
        /// Why it is needed.
        need: &'static str,
        /// The columns found.
        found: String,
    },
    /// The same column twice in the header.
    #[error("{path}: line 1 (header): column '{column}' appears twice")]
    DuplicateColumn {
        /// The file.
        path: String,
        /// The column.
        column: String,
    },
    /// A value is not a finite number.
    #[error("{path}: line {line}, column '{column}': {value:?} is not a finite number")]
    BadValue {
        /// The file.
        path: String,
        /// Line number (1 = header).
        line: u64,
        /// The column.
        column: String,
        /// The text found.
        value: String,
    },
    /// An angle beyond [`MAX_ANGLE_RAD`].
    #[error("{path}: line {line}, column 'theta_fb_rad': {value} rad is beyond ±{max:e} rad (is it in radians?)")]
    AngleOutOfRange {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// The angle.
        value: f64,
        /// The limit.
        max: f64,
    },
    /// A row has more or fewer fields than the header.
    #[error("{path}: line {line}: {found} fields, the header has {expected}")]
    ShortRow {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// Fields found.
        found: usize,
        /// Fields in the header.
        expected: usize,
    },
    /// A line is longer than [`MAX_LINE_BYTES`].
    #[error(
        "{path}: line {line} is longer than {limit} bytes: not a run log (CSV with a header row, one row per control period)"
    )]
    LineTooLong {
        /// The file.
        path: String,
        /// Line number (1 = header).
        line: u64,
        /// The limit in bytes.
        limit: usize,
    },
    /// The header has more than [`MAX_COLUMNS`] columns.
    #[error("{path}: line 1 (header): {found} columns, at most {max} are accepted: not a run log")]
    TooManyColumns {
        /// The file.
        path: String,
        /// Columns found.
        found: usize,
        /// The limit.
        max: usize,
    },
    /// The CSV itself is malformed.
    #[error("{path}: line {line}: malformed CSV: {message}")]
    Csv {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// The parser's message.
        message: String,
    },
    /// Time does not increase.
    #[error(
        "{path}: line {line}, column 't_s': time {t} s is not after the previous row's {prev} s (time must increase)"
    )]
    NonMonotonicTime {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// This row's time.
        t: f64,
        /// The previous row's time.
        prev: f64,
    },
    /// The log covers too few electrical periods.
    #[error(
        "{path}: too short: the rotor moved {periods:.2} electrical periods over {rows} rows (lines 2–{last_line}); at least {needed} are needed ({})",
        if *periods < 0.01 { "it stands still: log a servo run at a constant speed" } else { "run longer or faster" }
    )]
    TooShort {
        /// The file.
        path: String,
        /// Electrical periods covered.
        periods: f64,
        /// Periods needed.
        needed: f64,
        /// Data rows.
        rows: usize,
        /// Last line number.
        last_line: u64,
    },
}

/// Reads a run log from a file, streaming (see the module's "Cost").
pub fn read_log(path: &Path, opts: &LogOptions) -> Result<RunLog, LogError> {
    let name = path.display().to_string();
    let file = std::fs::File::open(path).map_err(|source| LogError::Io { path: name.clone(), source })?;
    parse_log(file, &name, opts)
}

/// A CSV reader over `reader` for logs and tables: no quoting (numbers only, so a record is
/// a line), fields trimmed, any number of fields per row (checked by the caller), lines
/// bounded by [`MAX_LINE_BYTES`].
pub(crate) fn bounded_csv<R: Read>(reader: R) -> csv::Reader<LineLimited<R>> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .quoting(false)
        .trim(csv::Trim::All)
        .from_reader(LineLimited::new(reader, MAX_LINE_BYTES))
}

/// What went wrong in the CSV reader: a line too long, an I/O error, or malformed CSV.
pub(crate) enum CsvFailure {
    LineTooLong { line: u64, limit: usize },
    Io(std::io::Error),
    Malformed { line: u64, message: String },
}

impl CsvFailure {
    pub(crate) fn of(e: csv::Error) -> CsvFailure {
        let line = e.position().map_or(0, |p| p.line());
        let message = printable(e.to_string().as_bytes(), 200);
        match e.into_kind() {
            csv::ErrorKind::Io(io) => match LineTooLong::from_io(&io) {
                Some(t) => CsvFailure::LineTooLong { line: t.line, limit: t.limit },
                None => CsvFailure::Io(io),
            },
            _ => CsvFailure::Malformed { line, message },
        }
    }
}

/// The header's names: the first one without a byte-order mark, surrounding `"` removed
/// (a header quoted by a spreadsheet), control characters escaped and long names cut.
pub(crate) fn header_names(rec: &csv::ByteRecord) -> Vec<String> {
    rec.iter()
        .enumerate()
        .map(|(i, f)| {
            let f = if i == 0 { f.strip_prefix("\u{feff}".as_bytes()).unwrap_or(f) } else { f };
            let f = f.strip_prefix(b"\"").and_then(|f| f.strip_suffix(b"\"")).unwrap_or(f);
            printable(f, SHOWN_CHARS)
        })
        .collect()
}

/// At most [`SHOWN_COLUMNS`] names, comma-separated, then how many more.
pub(crate) fn column_list(names: &[String]) -> String {
    let mut s = names.iter().take(SHOWN_COLUMNS).cloned().collect::<Vec<_>>().join(", ");
    if names.len() > SHOWN_COLUMNS {
        s += &format!(", … ({} columns in all)", names.len());
    }
    s
}

#[derive(Clone, Copy)]
enum Col {
    T,
    Theta,
    Iq,
    Ia,
    Ib,
    IqCmd,
    Skip,
}

/// Parses a run log from any reader; `source` names it in errors.
pub fn parse_log<R: Read>(reader: R, source: &str, opts: &LogOptions) -> Result<RunLog, LogError> {
    let path = source.to_string();
    let mut rdr = bounded_csv(reader);
    let mut rec = csv::ByteRecord::new();
    let csv_err = |e: csv::Error, path: &str| {
        let path = path.to_string();
        match CsvFailure::of(e) {
            CsvFailure::LineTooLong { line, limit } => LogError::LineTooLong { path, line, limit },
            CsvFailure::Io(source) => LogError::Io { path, source },
            CsvFailure::Malformed { line, message } => LogError::Csv { path, line, message },
        }
    };
    if !rdr.read_byte_record(&mut rec).map_err(|e| csv_err(e, &path))? {
        return Err(LogError::Empty {
            path, what: "empty file: expected a header row (t_s, theta_fb_rad, i_q_a, …)"
        });
    }
    if rec.len() > MAX_COLUMNS {
        return Err(LogError::TooManyColumns { path, found: rec.len(), max: MAX_COLUMNS });
    }
    let header = header_names(&rec);
    let mut cols = Vec::with_capacity(header.len());
    let mut ignored = Vec::new();
    let mut seen = std::collections::HashSet::with_capacity(header.len());
    for h in &header {
        if !seen.insert(h.as_str()) {
            return Err(LogError::DuplicateColumn { path, column: h.clone() });
        }
        cols.push(match h.as_str() {
            "t_s" => Col::T,
            "theta_fb_rad" => Col::Theta,
            "i_q_a" => Col::Iq,
            "i_a_a" => Col::Ia,
            "i_b_a" => Col::Ib,
            "iq_cmd_a" => Col::IqCmd,
            other => {
                if !KNOWN_COLUMNS.contains(&other) {
                    ignored.push(other.to_string());
                }
                Col::Skip
            }
        });
    }
    let has = |c: &str| seen.contains(c);
    let missing = |column: &'static str, need: &'static str| LogError::MissingColumn {
        path: path.clone(),
        column,
        need,
        found: column_list(&header),
    };
    if !has("t_s") {
        return Err(missing("t_s", "time in s"));
    }
    if !has("theta_fb_rad") {
        return Err(missing("theta_fb_rad", "encoder angle in rad"));
    }
    let iq_source = if has("i_q_a") {
        IqSource::Column
    } else if has("i_a_a") && has("i_b_a") {
        IqSource::Park
    } else if has("i_a_a") {
        return Err(missing("i_b_a", "i_q_a is absent, so both phase currents i_a_a and i_b_a are needed"));
    } else {
        return Err(missing("i_q_a", "torque current in A; or give both i_a_a and i_b_a"));
    };
    let want_cmd = has("iq_cmd_a");

    let mut t = Vec::new();
    let mut th = Vec::new();
    let mut iq = Vec::new();
    let mut ia = Vec::new();
    let mut ib = Vec::new();
    let mut cmd = Vec::new();
    let ncol = header.len();
    let mut line: u64 = 1;
    let mut prev_t = f64::NEG_INFINITY;
    loop {
        match rdr.read_byte_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_err(e, &path)),
        }
        line = rec.position().map_or(line + 1, |p| p.line());
        if rec.len() == 1 && rec.get(0).is_some_and(<[u8]>::is_empty) {
            continue; // blank line
        }
        if rec.len() != ncol {
            return Err(LogError::ShortRow { path, line, found: rec.len(), expected: ncol });
        }
        for (i, c) in cols.iter().enumerate() {
            let target = match c {
                Col::Skip => continue,
                Col::T => &mut t,
                Col::Theta => &mut th,
                Col::Iq => &mut iq,
                Col::Ia if iq_source == IqSource::Park => &mut ia,
                Col::Ib if iq_source == IqSource::Park => &mut ib,
                Col::IqCmd => &mut cmd,
                Col::Ia | Col::Ib => continue,
            };
            let field = &rec[i];
            let v = std::str::from_utf8(field).ok().and_then(|s| s.parse::<f64>().ok()).filter(|v| v.is_finite());
            let Some(v) = v else {
                return Err(LogError::BadValue {
                    path,
                    line,
                    column: header[i].clone(),
                    value: printable(field, SHOWN_CHARS),
                });
            };
            target.push(v);
        }
        let thn = *th.last().expect("theta_fb_rad is a column");
        if thn.abs() > MAX_ANGLE_RAD {
            return Err(LogError::AngleOutOfRange { path, line, value: thn, max: MAX_ANGLE_RAD });
        }
        let tn = *t.last().expect("t_s is a column");
        if tn <= prev_t {
            return Err(LogError::NonMonotonicTime { path, line, t: tn, prev: prev_t });
        }
        prev_t = tn;
    }
    if t.is_empty() {
        return Err(LogError::Empty { path, what: "no data rows after the header" });
    }
    if iq_source == IqSource::Park {
        let nr = f64::from(opts.pole_pairs);
        iq = th.iter().zip(ia.iter().zip(&ib)).map(|(&th, (&a, &b))| park_q(nr * th, a, b)).collect();
    }
    let log = RunLog {
        source: path,
        t_s: t,
        theta_fb_rad: th,
        i_q_a: iq,
        iq_cmd_a: want_cmd.then_some(cmd),
        iq_source,
        ignored_columns: ignored,
    };
    log.check_length(opts, line)?;
    Ok(log)
}

/// `i_q = −i_a sin θe + i_b cos θe`.
#[inline]
fn park_q(theta_e: f64, i_a: f64, i_b: f64) -> f64 {
    let (s, c) = theta_e.sin_cos();
    -i_a * s + i_b * c
}

impl RunLog {
    /// A log from simulator rows (what `stepdamp simulate --log` or the planner would write),
    /// without going through a file.
    pub fn from_rows(rows: &[LogRow], source: &str) -> RunLog {
        RunLog {
            source: source.to_string(),
            t_s: rows.iter().map(|r| r.t_s).collect(),
            theta_fb_rad: rows.iter().map(|r| r.theta_fb_rad).collect(),
            i_q_a: rows.iter().map(|r| r.i_q_a).collect(),
            iq_cmd_a: Some(rows.iter().map(|r| r.iq_cmd_a).collect()),
            iq_source: IqSource::Column,
            ignored_columns: Vec::new(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Electrical periods the rotor covered: `Nr·|θ_end − θ_start| / 2π`.
    pub fn electrical_periods(&self, pole_pairs: u16) -> f64 {
        match (self.theta_fb_rad.first(), self.theta_fb_rad.last()) {
            (Some(a), Some(b)) => f64::from(pole_pairs) * (b - a).abs() / std::f64::consts::TAU,
            _ => 0.0,
        }
    }

    /// Duration in s (last minus first time).
    pub fn duration_s(&self) -> f64 {
        match (self.t_s.first(), self.t_s.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }

    /// Checks that the log covers `opts.min_electrical_periods`.
    fn check_length(&self, opts: &LogOptions, last_line: u64) -> Result<(), LogError> {
        let periods = self.electrical_periods(opts.pole_pairs);
        if periods < opts.min_electrical_periods {
            return Err(LogError::TooShort {
                path: self.source.clone(),
                periods,
                needed: opts.min_electrical_periods,
                rows: self.len(),
                last_line,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
