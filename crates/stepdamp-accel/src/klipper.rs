//! Klipper's motion-analysis logs (`scripts/motan/data_logger.py`): a bounded, streaming
//! reader of the `.json.gz` file into the accelerometer route's samples, each with its time,
//! the acceleration projected on the motor's axis and the commanded electrical angle from the
//! stepper's step queue; and the log cut into the stretches ([`Segment`]) the ripple fit
//! ([`crate::ripple::identify_ripple`]) takes as captures.
//!
//! The format and the rules, with the lines of Klipper they come from:
//! `docs/files.md#klippers-motion-analysis-logs`; how to record a log:
//! `docs/accelerometer.md#klippers-motion-analysis-logs`. In short:
//!
//! - **Framing.** One gzip stream of JSON messages, each ended by `0x03` ([`frame`]). The
//!   `.index.gz` beside it only helps a reader seek; everything needed is in `.json.gz`.
//! - **Configuration.** The `objects/subscribe` answer (`"id": "status"`) holds
//!   `configfile.settings`: `printer.kinematics`, the stepper's `microsteps` and
//!   `full_steps_per_rotation`, and its TMC driver's `mcu_phase_offset`.
//! - **Accelerometer.** `"q": "accelerometer:<name>"` (or the older `adxl345:<name>`),
//!   `params.data` = `[[time, x, y, z], …]`, print time (s) and mm/s².
//! - **Steps.** `"q": "stepq:<stepper>"`, decoded by [`motion`].
//! - **Angle.** `θe = 2π·(p + mcu_phase_offset)/(4·microsteps)`, `p` the commanded MCU
//!   position (microsteps) at the sample's time: readlog.py's `step_phase` (phase =
//!   `(mcu_pos + mcu_phase_offset) mod 4·microsteps`, readlog.py:316–354) made continuous.

mod frame;
pub mod motion;
pub mod plan;
mod read;
pub mod segment;
pub mod table_step;

use crate::capture::{Axis, Commanded};
pub use read::{read_file, read_log};
pub use segment::Segment;
use serde_json::Value;
use stepdamp_out::input::printable;

/// The most bytes decompressed from one log (1 GiB): an ADXL345 at 3200 Hz with a stepper
/// queue logs about 0.3 MB/s, so an hour fits; a zip bomb stops here.
pub const MAX_DECOMPRESSED_BYTES: u64 = 1 << 30;
/// The most bytes of one message (4 MiB): a batch is tens of kB (0.1 s of samples,
/// adxl345.py:199; 0.5 s of steps, bulk_sensor.py:20), and a message is parsed whole (a few
/// tens of bytes of memory per number).
pub const MAX_RECORD_BYTES: usize = 1 << 22;
/// The most accelerometer samples kept (2²¹, 11 minutes at 3200 Hz; 16 bytes each, and
/// 40 more for the commanded motion).
pub const MAX_SAMPLES: usize = 1 << 21;
/// The most steps kept (2²², 5.5 minutes at 4 rev/s of a 200-step motor at 16 microsteps;
/// 24 bytes each).
pub const MAX_STEPS: usize = 1 << 22;
/// The most characters of a value shown in an error.
pub const MAX_SHOWN_CHARS: usize = 60;

/// The longest key or explanation a message quotes from the log (characters).
pub const MAX_MESSAGE_CHARS: usize = 400;

/// The kinematics the projection knows (`printer.kinematics`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kinematics {
    /// `cartesian`: `stepper_x` moves X, `stepper_y` moves Y.
    Cartesian,
    /// `corexy`: `x = (a + b)/2`, `y = (a − b)/2` (corexy.py, `calc_position`), so the belt
    /// of `stepper_x` (A) moves by `x + y` and that of `stepper_y` (B) by `x − y`.
    CoreXy,
}

impl Kinematics {
    /// The weights `(wx, wy)` that make the sample's `wx·x + wy·y` the acceleration of the
    /// motor's belt: cartesian one axis, CoreXY `x + y` (A) or `x − y` (B).
    pub fn projection(self, axis: Axis) -> (f64, f64) {
        match (self, axis) {
            (Kinematics::Cartesian, Axis::X) => (1.0, 0.0),
            (Kinematics::Cartesian, Axis::Y) => (0.0, 1.0),
            (Kinematics::CoreXy, Axis::X) => (1.0, 1.0),
            (Kinematics::CoreXy, Axis::Y) => (1.0, -1.0),
        }
    }

    /// The kinematics of a [`Kinematics::name`], `None` for any other text.
    pub fn from_name(name: &str) -> Option<Self> {
        [Kinematics::Cartesian, Kinematics::CoreXy].into_iter().find(|k| k.name() == name)
    }

    /// The name Klipper's configuration uses.
    pub fn name(self) -> &'static str {
        match self {
            Kinematics::Cartesian => "cartesian",
            Kinematics::CoreXy => "corexy",
        }
    }
}

/// What the reader is told besides the log.
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperOptions {
    /// The motor: `X` reads `stepper_x`, `Y` reads `stepper_y` (on CoreXY the A and B motors).
    pub axis: Axis,
    /// The accelerometer's name (`adxl345` for `[adxl345]`); `None` takes the only one.
    pub accelerometer: Option<String>,
    /// The trial the driver's table carried during the whole log, if any (Klipper has no
    /// `M973`: a trial is a table of its own, e.g. a TMC wave table written for it).
    pub trial: Option<TrialShift>,
}

/// A known shift of the commanded current vector's angle, `U·sin(k·θe + φ)` (rad, `θe` the
/// log's electrical angle): the trial that fixes the scale of the head's response
/// (`docs/accelerometer.md#identifying-the-ripple-from-captures`). A Prusa `M973` trial
/// `H<k> C<mag> A<φ>` is `U = 4·mag` in firmware ≥ 6.3.1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialShift {
    /// The order `k`, 1..=16.
    pub harmonic: u32,
    /// `U` (rad).
    pub amplitude_rad: f64,
    /// `φ` (rad).
    pub phase_rad: f64,
}

/// A log as read.
#[derive(Debug, Clone, PartialEq)]
pub struct Log {
    /// Where it was read from.
    pub source: String,
    /// The stepper section (`stepper_x`, `stepper_y`).
    pub stepper: String,
    /// The accelerometer's subscription (`accelerometer:adxl345`).
    pub accelerometer: String,
    /// The trial during the log ([`KlipperOptions::trial`]).
    pub trial: Option<TrialShift>,
    /// The kinematics.
    pub kinematics: Kinematics,
    /// Microsteps per full step (`microsteps`).
    pub microsteps: u32,
    /// Full steps per motor revolution (`full_steps_per_rotation`, 200 when absent).
    pub full_steps_per_rotation: u32,
    /// The TMC driver's `mcu_phase_offset` (microsteps), `None` without one (the angle is
    /// then relative to an unknown offset, as readlog.py takes 0).
    pub mcu_phase_offset: Option<i64>,
    /// The samples' print times (s), increasing.
    pub times_s: Vec<f64>,
    /// The samples projected on the motor's belt ([`Kinematics::projection`], m/s²).
    pub accel_m_s2: Vec<f64>,
    /// The commanded motion at each sample; `electrical_rad` as the module doc says,
    /// `motor_rev` the MCU position in revolutions, speeds and accelerations signed alike.
    pub commanded: Vec<Commanded>,
    /// The steps read.
    pub steps: usize,
    /// The messages read.
    pub records: u64,
    /// Messages that are not JSON and name none of the subscriptions read (readlog.py:637–641
    /// skips them too); `0` in a log the logger wrote whole.
    pub skipped_records: u64,
    /// The largest `errors` and `overflows` the accelerometer reported (samples it dropped).
    pub accel_errors: u64,
    /// See [`Self::accel_errors`].
    pub accel_overflows: u64,
}

impl Log {
    /// Electrical periods per revolution, `full_steps_per_rotation / 4`.
    pub fn periods_per_rev(&self) -> u32 {
        self.full_steps_per_rotation / 4
    }
}

/// Why a log cannot be read; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KlipperError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// The source.
        file: String,
        /// The error.
        message: String,
    },
    /// Not a whole gzip stream.
    #[error("{file}: after {offset} decompressed bytes: {message}")]
    Gzip {
        /// The source.
        file: String,
        /// Bytes decompressed before the error.
        offset: u64,
        /// Why.
        message: String,
    },
    /// A bound of the reader.
    #[error("{file}: record {record}: more than {limit} {what}: {why}")]
    TooMany {
        /// The source.
        file: String,
        /// The record (1-based).
        record: u64,
        /// Of what.
        what: &'static str,
        /// The bound.
        limit: u64,
        /// Why.
        why: &'static str,
    },
    /// A message, or a value in it, is not what the logger writes.
    #[error("{file}: record {record}: {key} = {value}: expected {expected}")]
    Record {
        /// The source.
        file: String,
        /// The record (1-based).
        record: u64,
        /// The key (a dotted path).
        key: String,
        /// The value as written (cut).
        value: String,
        /// What is allowed.
        expected: String,
    },
    /// Something the route needs is not in the log.
    #[error("{file}: {what}")]
    Missing {
        /// The source.
        file: String,
        /// What, and how to record it.
        what: String,
    },
}

/// A JSON value as written, cut to [`MAX_SHOWN_CHARS`], control characters escaped
/// (`serde_json` escapes those below U+0020 but writes `DEL` and C1 controls raw).
pub(crate) fn shown(v: &Value) -> String {
    printable(v.to_string().as_bytes(), MAX_SHOWN_CHARS)
}

/// Text built from the log's own keys and names (a driver's section, an accelerometer's
/// name) as it goes into a message: control characters escaped, cut to
/// [`MAX_MESSAGE_CHARS`].
pub(crate) fn message_text(s: &str) -> String {
    printable(s.as_bytes(), MAX_MESSAGE_CHARS)
}

#[cfg(test)]
mod tests;
