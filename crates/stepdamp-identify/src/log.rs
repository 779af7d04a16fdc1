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
//! | `i_d_a` | A | optional: the measured flux current `i_d` in the encoder's frame; without it `i_d` comes from `i_a_a`, `i_b_a` when they are logged (`i_d = i_a cos θe + i_b sin θe`), else it is taken as the plan's servo command, 0 |
//! | `theta_cmd_rad`, `omega_fb_rad_s` | | read when present, not needed |
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
//! 0.5 µs per row of the run log (docs/files.md) in a release build (200 000 rows in ≈ 0.1 s). Input that is
//! not a log (`/dev/zero`, a file of zeros) is refused after at most [`MAX_LINE_BYTES`].

use std::io::Read;
use std::path::Path;
use stepdamp_out::input::{LineLimited, LineTooLong, printable};
use stepdamp_profile::LogRow;

/// The columns a run log must or may carry (docs/files.md, "Run log").
pub const KNOWN_COLUMNS: [&str; 11] = stepdamp_profile::runlog::LOG_COLUMNS;

/// Longest line accepted, in bytes. A run-log row is about 200 bytes and a header of
/// [`MAX_COLUMNS`] 60-character names 60 KiB; anything longer is not a run log, and the
/// bound keeps one line's buffer small whatever the input.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Largest `|θ_fb|` accepted, rad (160 million revolutions: days of logging at 1000 rad/s).
/// Beyond it `sin(k·Nr·θ)` loses its meaning in `f64` (the spacing of `f64` near
/// `Nr·θ = 5·10¹⁰` is 8·10⁻⁶ rad, and grows with θ) and the Park transform overflows to NaN.
pub const MAX_ANGLE_RAD: f64 = 1e9;

/// Most columns a header may have (the run log has 11; tools add a few dozen at most).
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
    /// Measured flux current `i_d` in A (encoder frame): the `i_d_a` column, or the Park
    /// transform of the phase currents when they are logged; `None` when neither is (then
    /// `i_d = 0`, the servo runs' command, is assumed). With a `[motor.flux]` section a
    /// non-zero `i_d` makes torque (docs/design.md#real-motors-flux-harmonics), which the
    /// encoder fit counts.
    pub i_d_a: Option<Vec<f64>>,
    /// Where `i_q` came from.
    pub iq_source: IqSource,
    /// Header columns that were not used (unknown names), in file order.
    pub ignored_columns: Vec<String>,
    /// The phase currents and applied voltages, kept for a run fast enough for the back-EMF
    /// fit of the flux linkage ([`crate::emf::is_emf_run`]) when the log has all four
    /// columns; `None` otherwise (a slow run's are read, checked like every column, and
    /// dropped: they cost memory only while the log is read).
    pub phases: Option<PhaseSignals>,
}

/// The winding signals of a run log, each as long as the log (docs/files.md#run-log-csv).
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseSignals {
    /// Sampled phase A current in A, at `t_s`.
    pub i_a_a: Vec<f64>,
    /// Sampled phase B current in A, at `t_s`.
    pub i_b_a: Vec<f64>,
    /// Mean voltage across winding A over `[t_s, t_s + Ts)` in V, as applied.
    pub v_a_v: Vec<f64>,
    /// Mean voltage across winding B over `[t_s, t_s + Ts)` in V, as applied.
    pub v_b_v: Vec<f64>,
}

/// The columns of [`PhaseSignals`], in its field order.
pub const PHASE_COLUMNS: [&str; 4] = ["i_a_a", "i_b_a", "v_a_v", "v_b_v"];

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
    /// A current or voltage beyond any stepper drive's (a sensorless log).
    #[error("{path}: line {line}, column '{column}': {value:e} {unit} is beyond ±{max:e} {unit} (is it in {unit}?)")]
    ValueOutOfRange {
        /// The file.
        path: String,
        /// Line number.
        line: u64,
        /// The column.
        column: &'static str,
        /// The value.
        value: f64,
        /// The limit.
        max: f64,
        /// Its unit.
        unit: &'static str,
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
    /// Columns given in memory (a DataFrame's) are not all the same length.
    #[error(
        "{path}: column '{column}' has {rows} rows, column '{first}' has {expected}: the columns of a log must be the same length"
    )]
    RaggedColumns {
        /// The log's name.
        path: String,
        /// The column of another length.
        column: String,
        /// Its rows.
        rows: usize,
        /// The first column.
        first: String,
        /// The first column's rows.
        expected: usize,
    },
    /// A column the reader uses was named without its values (in memory only).
    #[error("{path}: column '{column}' is given without its values (pass its array)")]
    ColumnWithoutValues {
        /// The log's name.
        path: String,
        /// The column.
        column: String,
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

/// What an empty encoder log is told it should have started with.
pub(crate) const EXPECTED_HEADER: &str = "empty file: expected a header row (t_s, theta_fb_rad, i_q_a, …)";

/// Parses a run log from any reader; `source` names it in errors.
pub fn parse_log<R: Read>(reader: R, source: &str, opts: &LogOptions) -> Result<RunLog, LogError> {
    let cols = columns::ColumnReader::open(reader, source, &KNOWN_COLUMNS, EXPECTED_HEADER)?;
    log_from_columns(cols, source, opts)
}

/// The rest of [`parse_log`] once the header is read: the same reader goes on to the rows.
pub(crate) fn log_from_columns<R: Read>(
    cols: columns::ColumnReader<'_, R>,
    source: &str,
    opts: &LogOptions,
) -> Result<RunLog, LogError> {
    if !cols.has("t_s") {
        return Err(cols.missing("t_s", "time in s"));
    }
    if !cols.has("theta_fb_rad") {
        return Err(cols.missing("theta_fb_rad", "encoder angle in rad"));
    }
    let iq_source = if cols.has("i_q_a") {
        IqSource::Column
    } else if cols.has("i_a_a") && cols.has("i_b_a") {
        IqSource::Park
    } else if cols.has("i_a_a") {
        return Err(cols.missing("i_b_a", "i_q_a is absent, so both phase currents i_a_a and i_b_a are needed"));
    } else {
        return Err(cols.missing("i_q_a", "torque current in A; or give both i_a_a and i_b_a"));
    };
    let want_cmd = cols.has("iq_cmd_a");
    let want_id = cols.has("i_d_a");
    let want_phases = PHASE_COLUMNS.iter().all(|c| cols.has(c));
    // i_q logged, no i_d, phase currents without the voltages: the currents still give i_d.
    let id_from_currents =
        iq_source == IqSource::Column && !want_id && !want_phases && cols.has("i_a_a") && cols.has("i_b_a");
    let mut wanted = vec!["t_s", "theta_fb_rad"];
    match iq_source {
        IqSource::Column if id_from_currents => wanted.extend(["i_q_a", "i_a_a", "i_b_a"]),
        IqSource::Column => wanted.push("i_q_a"),
        IqSource::Park if want_phases => {}
        IqSource::Park => wanted.extend(["i_a_a", "i_b_a"]),
    }
    if want_cmd {
        wanted.push("iq_cmd_a");
    }
    if want_id {
        wanted.push("i_d_a");
    }
    if want_phases {
        wanted.extend(PHASE_COLUMNS);
    }
    let ignored = cols.ignored.clone();
    let path = source.to_string();
    let columns::Columns { values, last_line } = cols.read(&wanted, |line, row| {
        let th = row[1];
        if th.abs() > MAX_ANGLE_RAD {
            return Err(LogError::AngleOutOfRange { path: path.clone(), line, value: th, max: MAX_ANGLE_RAD });
        }
        Ok(())
    })?;
    let mut values = values.into_iter();
    let mut next = || values.next().unwrap_or_default();
    let (t, th) = (next(), next());
    let (iq, id_park) = match iq_source {
        IqSource::Column if id_from_currents => {
            let (iq, ia, ib) = (next(), next(), next());
            (Some(iq), Some(park_all(opts.pole_pairs, &th, &ia, &ib, park_d)))
        }
        IqSource::Column => (Some(next()), None),
        IqSource::Park if want_phases => (None, None),
        IqSource::Park => {
            let (ia, ib) = (next(), next());
            (
                Some(park_all(opts.pole_pairs, &th, &ia, &ib, park_q)),
                Some(park_all(opts.pole_pairs, &th, &ia, &ib, park_d)),
            )
        }
    };
    let cmd = want_cmd.then(&mut next);
    let id_column = want_id.then(&mut next);
    let phases = want_phases.then(|| PhaseSignals { i_a_a: next(), i_b_a: next(), v_a_v: next(), v_b_v: next() });
    let iq = match (iq, &phases) {
        (Some(iq), _) => iq,
        (None, Some(p)) => park_all(opts.pole_pairs, &th, &p.i_a_a, &p.i_b_a, park_q),
        (None, None) => Vec::new(),
    };
    // The logged i_d first; else the phase currents' (before a slow run's are dropped).
    let id = id_column
        .or(id_park)
        .or_else(|| phases.as_ref().map(|p| park_all(opts.pole_pairs, &th, &p.i_a_a, &p.i_b_a, park_d)));
    let mut log = RunLog {
        source: path,
        t_s: t,
        theta_fb_rad: th,
        i_q_a: iq,
        iq_cmd_a: cmd,
        i_d_a: id,
        iq_source,
        ignored_columns: ignored,
        phases,
    };
    log.check_length(opts, last_line)?;
    if !crate::emf::is_emf_run(&log, opts.pole_pairs) {
        log.phases = None;
    }
    Ok(log)
}

/// `i_q` or `i_d` of every sample ([`park_q`] or [`park_d`]) at `Nr·θ_fb`.
fn park_all(pole_pairs: u16, th: &[f64], ia: &[f64], ib: &[f64], park: fn(f64, f64, f64) -> f64) -> Vec<f64> {
    let nr = f64::from(pole_pairs);
    th.iter().zip(ia.iter().zip(ib)).map(|(&th, (&a, &b))| park(nr * th, a, b)).collect()
}

/// `i_d = i_a cos θe + i_b sin θe`.
#[inline]
fn park_d(theta_e: f64, i_a: f64, i_b: f64) -> f64 {
    let (s, c) = theta_e.sin_cos();
    i_a * c + i_b * s
}

/// `i_q = −i_a sin θe + i_b cos θe`.
#[inline]
fn park_q(theta_e: f64, i_a: f64, i_b: f64) -> f64 {
    let (s, c) = theta_e.sin_cos();
    -i_a * s + i_b * c
}

impl RunLog {
    /// A log from simulator rows (what `stepdamp simulate --log` or the planner would write),
    /// without going through a file; it keeps the phase signals of every run (the back-EMF
    /// fit picks the runs fast enough for it).
    pub fn from_rows(rows: &[LogRow], source: &str) -> RunLog {
        let col = |f: fn(&LogRow) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
        RunLog {
            source: source.to_string(),
            t_s: rows.iter().map(|r| r.t_s).collect(),
            theta_fb_rad: rows.iter().map(|r| r.theta_fb_rad).collect(),
            i_q_a: rows.iter().map(|r| r.i_q_a).collect(),
            iq_cmd_a: Some(rows.iter().map(|r| r.iq_cmd_a).collect()),
            i_d_a: Some(col(|r| r.i_d_a)),
            iq_source: IqSource::Column,
            ignored_columns: Vec::new(),
            phases: Some(PhaseSignals {
                i_a_a: col(|r| r.i_a_a),
                i_b_a: col(|r| r.i_b_a),
                v_a_v: col(|r| r.v_a_v),
                v_b_v: col(|r| r.v_b_v),
            }),
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

pub(crate) mod columns;

pub use columns::LogColumns;

#[cfg(test)]
mod tests;
