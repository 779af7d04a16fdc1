//! Sensorless run logs: an open-loop run as the drive itself records it, with no encoder
//! (docs/files.md, "Run log"; docs/sensorless.md).
//!
//! | column | unit | |
//! |---|---|---|
//! | `t_s` | s | strictly increasing, from the start of the run (standstill included) |
//! | `theta_cmd_rad` | rad, mechanical | the commanded angle (`θe_cmd / Nr`) |
//! | `i_a_a`, `i_b_a` | A | the sampled phase currents at `t_s` |
//! | `v_a_v`, `v_b_v` | V | the mean voltage across each winding over `[t_s, t_s + Ts)`, after the modulator's limiting (the voltage actually applied in that interval) |
//!
//! Unknown columns are ignored and listed in [`SensorlessLog::ignored_columns`] (the servo
//! log's known columns, such as `theta_fb_rad` or `i_q_a`, are not read and not listed).
//! Errors are the run log's ([`crate::log::LogError`]): file, line and column; a current
//! beyond [`MAX_CURRENT_A`] or a voltage beyond [`MAX_VOLTAGE_V`] is refused where it is.

use crate::log::columns::{ColumnReader, Columns};
use crate::log::{KNOWN_COLUMNS, LogError, MAX_ANGLE_RAD};
use std::io::Read;

/// The columns a sensorless log must carry, in the order of [`SensorlessLog`]'s fields.
pub const SENSORLESS_COLUMNS: [&str; 6] = ["t_s", "theta_cmd_rad", "i_a_a", "i_b_a", "v_a_v", "v_b_v"];

/// Largest `|i|` accepted, A: ten times the largest holding current a profile may have
/// would still be 100 A; beyond 10⁴ A a value is not a stepper's current.
pub const MAX_CURRENT_A: f64 = 1e4;

/// Largest `|v|` accepted, V: beyond 10⁵ V a value is not a stepper drive's voltage.
pub const MAX_VOLTAGE_V: f64 = 1e5;

/// What each column of [`SENSORLESS_COLUMNS`] is (for the missing-column message).
const NEEDS: [&str; 6] = [
    "time in s",
    "commanded mechanical angle in rad",
    "phase A current in A",
    "phase B current in A",
    "mean phase A winding voltage over the period in V",
    "mean phase B winding voltage over the period in V",
];

/// An open-loop run log without an encoder. All vectors have the same length.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorlessLog {
    /// Name of the source (the file path), used in messages.
    pub source: String,
    /// Time in s, strictly increasing.
    pub t_s: Vec<f64>,
    /// Commanded mechanical angle in rad.
    pub theta_cmd_rad: Vec<f64>,
    /// Phase A current in A.
    pub i_a_a: Vec<f64>,
    /// Phase B current in A.
    pub i_b_a: Vec<f64>,
    /// Mean winding A voltage over `[t_s, t_s + Ts)` in V.
    pub v_a_v: Vec<f64>,
    /// Mean winding B voltage over `[t_s, t_s + Ts)` in V.
    pub v_b_v: Vec<f64>,
    /// Header columns that were not used (unknown names), in file order.
    pub ignored_columns: Vec<String>,
}

/// Parses a sensorless log from any reader; `source` names it in errors.
pub fn parse_sensorless_log<R: Read>(reader: R, source: &str) -> Result<SensorlessLog, LogError> {
    let cols = ColumnReader::open(reader, source, &KNOWN_COLUMNS, EXPECTED_HEADER)?;
    sensorless_log_from_columns(cols, source)
}

/// What an empty sensorless log is told it should have started with.
pub(crate) const EXPECTED_HEADER: &str =
    "empty file: expected a header row (t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v, v_b_v)";

/// The rest of [`parse_sensorless_log`] once the header is read: the same reader goes on
/// to the rows.
pub(crate) fn sensorless_log_from_columns<R: Read>(
    cols: ColumnReader<'_, R>,
    source: &str,
) -> Result<SensorlessLog, LogError> {
    for (c, need) in SENSORLESS_COLUMNS.iter().zip(NEEDS) {
        if !cols.has(c) {
            return Err(cols.missing(c, need));
        }
    }
    let ignored_columns = cols.ignored.clone();
    let path = source.to_string();
    let Columns { values, .. } = cols.read(&SENSORLESS_COLUMNS, |line, row| {
        let th = row[1];
        if th.abs() > MAX_ANGLE_RAD {
            return Err(LogError::AngleOutOfRange { path: path.clone(), line, value: th, max: MAX_ANGLE_RAD });
        }
        for (i, (max, unit)) in [(MAX_CURRENT_A, "A"), (MAX_CURRENT_A, "A"), (MAX_VOLTAGE_V, "V"), (MAX_VOLTAGE_V, "V")]
            .into_iter()
            .enumerate()
        {
            let value = row[2 + i];
            if value.abs() > max {
                let column = SENSORLESS_COLUMNS[2 + i];
                return Err(LogError::ValueOutOfRange { path: path.clone(), line, column, value, max, unit });
            }
        }
        Ok(())
    })?;
    let [t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v, v_b_v]: [Vec<f64>; 6] =
        values.try_into().unwrap_or_else(|_| Default::default());
    Ok(SensorlessLog { source: path, t_s, theta_cmd_rad, i_a_a, i_b_a, v_a_v, v_b_v, ignored_columns })
}

impl SensorlessLog {
    /// A log from simulator rows, without going through a file.
    pub fn from_rows(rows: &[stepdamp_profile::LogRow], source: &str) -> SensorlessLog {
        let col = |f: fn(&stepdamp_profile::LogRow) -> f64| rows.iter().map(f).collect();
        SensorlessLog {
            source: source.to_string(),
            t_s: col(|r| r.t_s),
            theta_cmd_rad: col(|r| r.theta_cmd_rad),
            i_a_a: col(|r| r.i_a_a),
            i_b_a: col(|r| r.i_b_a),
            v_a_v: col(|r| r.v_a_v),
            v_b_v: col(|r| r.v_b_v),
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
}
