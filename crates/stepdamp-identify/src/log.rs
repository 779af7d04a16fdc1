//! Run logs (design.md §6): CSV with a header row, one row per control period, read into
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
//! increase, a log that covers too few electrical periods.
//!
//! # Cost
//!
//! One pass over the bytes with the `csv` crate, parsing only the needed columns: about
//! 0.5 µs per row of the §6 log in a release build (200 000 rows in ≈ 0.1 s).

use std::io::Read;
use std::path::Path;
use stepdamp_profile::LogRow;

/// The columns a run log must or may carry (design.md §6).
pub const KNOWN_COLUMNS: [&str; 9] =
    ["t_s", "theta_cmd_rad", "theta_fb_rad", "omega_fb_rad_s", "i_a_a", "i_b_a", "i_d_a", "i_q_a", "iq_cmd_a"];

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

/// Reads a run log from a file.
pub fn read_log(path: &Path, opts: &LogOptions) -> Result<RunLog, LogError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| LogError::Io { path: name.clone(), source })?;
    parse_log(&bytes[..], &name, opts)
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
    let mut rdr = csv::ReaderBuilder::new().has_headers(false).flexible(true).trim(csv::Trim::All).from_reader(reader);
    let mut rec = csv::ByteRecord::new();
    let csv_err = |e: csv::Error, path: &str| {
        let line = e.position().map_or(0, |p| p.line());
        match e.kind() {
            csv::ErrorKind::Io(_) => {
                LogError::Io { path: path.to_string(), source: std::io::Error::other(e.to_string()) }
            }
            _ => LogError::Csv { path: path.to_string(), line, message: e.to_string() },
        }
    };
    if !rdr.read_byte_record(&mut rec).map_err(|e| csv_err(e, &path))? {
        return Err(LogError::Empty {
            path, what: "empty file: expected a header row (t_s, theta_fb_rad, i_q_a, …)"
        });
    }
    let header: Vec<String> =
        rec.iter().map(|f| String::from_utf8_lossy(f).trim_start_matches('\u{feff}').to_string()).collect();
    let mut cols = Vec::with_capacity(header.len());
    let mut ignored = Vec::new();
    for (i, h) in header.iter().enumerate() {
        if header[..i].contains(h) {
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
    let has = |c: &str| header.iter().any(|h| h == c);
    let missing = |column: &'static str, need: &'static str| LogError::MissingColumn {
        path: path.clone(),
        column,
        need,
        found: header.join(", "),
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
                    value: String::from_utf8_lossy(field).into_owned(),
                });
            };
            target.push(v);
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
mod tests {
    use super::*;

    const HEAD: &str = "t_s,theta_fb_rad,i_q_a\n";

    /// A good log body: `rows` rows at 20 kHz, 1 rad/s.
    fn body(rows: usize) -> String {
        (0..rows).map(|i| format!("{},{},0.1\n", i as f64 * 5e-5, i as f64 * 5e-5)).collect()
    }

    fn parse(text: &str) -> Result<RunLog, LogError> {
        parse_log(text.as_bytes(), "run.csv", &LogOptions::new(50))
    }

    #[test]
    fn a_good_log_parses_in_any_column_order_and_names_unknown_columns() {
        let mut text = String::from("i_q_a,volts,theta_fb_rad,t_s,omega_fb_rad_s\n");
        for i in 0..2000 {
            text += &format!("0.2,1,{},{},0\n", i as f64 * 5e-4, i as f64 * 5e-5);
        }
        let log = parse(&text).unwrap();
        assert_eq!(log.len(), 2000);
        assert_eq!(log.ignored_columns, vec!["volts".to_string()]);
        assert_eq!((log.i_q_a[5], log.iq_source), (0.2, IqSource::Column));
        assert!(log.iq_cmd_a.is_none());
    }

    #[test]
    fn a_missing_column_names_the_file_the_header_line_and_the_column() {
        let e = parse("theta_fb_rad,i_q_a\n0,0\n").unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("line 1") && e.contains("'t_s'"), "{e}");
        let e = parse("t_s,i_q_a\n0,0\n").unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("'theta_fb_rad'"), "{e}");
        let e = parse("t_s,theta_fb_rad\n0,0\n").unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("'i_q_a'") && e.contains("i_a_a and i_b_a"), "{e}");
        let e = parse("t_s,theta_fb_rad,i_a_a\n0,0,0\n").unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("'i_b_a'"), "{e}");
        let e = parse("t_s,theta_fb_rad,i_q_a,t_s\n0,0,0,0\n").unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("twice"), "{e}");
    }

    #[test]
    fn time_that_does_not_increase_names_the_file_line_and_column() {
        let text = format!("{HEAD}0.0,0,0\n0.1,0,0\n0.1,0,0\n");
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("line 4") && e.contains("'t_s'") && e.contains("increase"), "{e}");
        let text = format!("{HEAD}0.0,0,0\n0.2,0,0\n0.1,0,0\n");
        assert!(parse(&text).unwrap_err().to_string().contains("line 4"));
    }

    #[test]
    fn nan_or_unparseable_values_name_the_file_line_and_column() {
        for bad in ["NaN", "inf", "abc", ""] {
            let text = format!("{HEAD}0.0,0,0\n0.00005,0,{bad}\n");
            let e = parse(&text).unwrap_err().to_string();
            assert!(e.contains("run.csv") && e.contains("line 3") && e.contains("'i_q_a'"), "{bad}: {e}");
        }
        let text = format!("{HEAD}{}0.5,0.5\n", body(3));
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("line 5") && e.contains("2 fields"), "{e}");
        let text = format!("{HEAD}{}0.5,0.5,0.1,7\n", body(3));
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("line 5") && e.contains("4 fields, the header has 3"), "{e}");
    }

    #[test]
    fn a_log_of_a_rotor_at_standstill_says_so() {
        let mut text = String::from(HEAD);
        for i in 0..6000 {
            text += &format!("{},0.1,0.2\n", i as f64 * 5e-5);
        }
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("0.00 electrical periods") && e.contains("stands still"), "{e}");
    }

    #[test]
    fn a_log_that_is_too_short_says_how_many_electrical_periods_it_covers() {
        // 1000 rows at 1 rad/s = 0.05 rad = 0.40 electrical periods of 2π/50.
        let e = parse(&format!("{HEAD}{}", body(1000))).unwrap_err().to_string();
        assert!(e.contains("run.csv") && e.contains("0.40 electrical periods") && e.contains("at least 2"), "{e}");
        assert!(e.contains("lines 2–1001"), "{e}");
        assert!(parse(&format!("{HEAD}{}", body(6000))).is_ok());
    }

    #[test]
    fn empty_and_unreadable_files_are_named() {
        assert!(parse("").unwrap_err().to_string().contains("run.csv: empty file"));
        assert!(parse(HEAD).unwrap_err().to_string().contains("run.csv: no data rows"));
        let e = read_log(Path::new("/no/such/dir/x.csv"), &LogOptions::new(50)).unwrap_err().to_string();
        assert!(e.contains("/no/such/dir/x.csv") && e.contains("cannot read"), "{e}");
    }
}
