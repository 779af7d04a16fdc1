//! Why a profile could not be used.

use std::path::PathBuf;
use stepdamp_core::limits::{Limit, Num};

/// Why a profile could not be used. Every variant names the file (or preset).
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Not valid TOML or not the profile's shape (unknown or missing key, wrong type).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message (names the key and the line).
        message: String,
    },
    /// A key is outside its physical range.
    #[error("{path}: {key} = {value}: must be in {limit}", value = Num(*.value))]
    OutOfRange {
        /// The file (or preset name).
        path: String,
        /// The key, e.g. `motor.detent[1].amplitude_nm`.
        key: String,
        /// The value given.
        value: f64,
        /// Its range, and why.
        limit: &'static Limit,
    },
    /// A key holds a value that contradicts another key or makes a derived quantity
    /// overflow.
    #[error("{path}: {key} = {value}: {reason}")]
    Invalid {
        /// The file (or preset name).
        path: String,
        /// The key, e.g. `drive.holding_current_a`.
        key: String,
        /// The value given, as written.
        value: String,
        /// What it must be.
        reason: String,
    },
    /// The controller refuses the profile (a relation its own checks hold).
    #[error("{path}: {source}")]
    Controller {
        /// The file (or preset name).
        path: String,
        /// The controller's reason.
        source: stepdamp_core::ConfigError,
    },
    /// A bare name that is not a preset.
    #[error("unknown motor '{name}': not a preset ({presets}){hint}", presets = crate::PRESETS.join(", "),
        hint = if *.file_exists { format!("; for the file, write ./{name}") } else { String::new() })]
    Unknown {
        /// The name given.
        name: String,
        /// A file of that name exists in the working directory.
        file_exists: bool,
    },
    /// A bare name that is a preset and also a file in the working directory.
    #[error("'{0}' is both a preset and a file here: write ./{0} for the file, or rename it")]
    Ambiguous(String),
    /// A path (it has a `/` or ends in `.toml`) that does not exist.
    #[error("{0}: no such profile file")]
    NoSuchFile(PathBuf),
}
