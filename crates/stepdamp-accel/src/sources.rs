//! The inputs of the ripple fit as a front end gives them: paths to Klipper motion-analysis
//! logs (gzip) or to Prusa captures (text), one kind, each Klipper log with the trial its
//! driver's table carried; read, checked against the motor and the axis, and fitted
//! (docs/accelerometer.md#identifying-the-ripple-from-captures). The CLI's
//! `identify --accel` and the Python binding both call [`read`] and [`Sources::fit`]; they
//! only name their options ([`Names`]).

use crate::capture::{AccelCapture, Axis, Reconstruction, SETTLE_S};
use crate::klipper::segment::MIN_SEGMENT_S;
use crate::klipper::{Kinematics, KlipperError, KlipperOptions, Log, TrialShift};
use crate::prusa::{MAX_NAME_CHARS, ReadError};
use crate::ripple::{RippleError, RippleFit, RippleOptions, identify_ripple};
use std::io::Read;
use std::path::{Path, PathBuf};
use stepdamp_out::input::printable;

/// What a front end calls the inputs, for messages: the CLI's `--accel`, `--axis`, `--motor`,
/// `--klipper-trial`; Python's argument names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Names {
    /// The paths (`--accel`).
    pub paths: &'static str,
    /// The axis (`--axis`).
    pub axis: &'static str,
    /// The motor profile (`--motor`).
    pub motor: &'static str,
    /// The Klipper logs' trials (`--klipper-trial`).
    pub trial: &'static str,
    /// The printer's kinematics (`--kinematics`).
    pub kinematics: &'static str,
}

/// The recordings read: Klipper logs or Prusa captures, never both.
#[derive(Debug, Clone)]
pub enum Sources {
    /// Klipper motion-analysis logs, each with its trial; the fit takes their stretches of
    /// steady motion ([`Log::segments`]).
    Klipper(Vec<Log>),
    /// Prusa `M973`/`M974` captures of every file, in order.
    Prusa(Vec<AccelCapture>),
}

/// Why the inputs cannot be read or fitted; one line each.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SourcesError {
    /// Klipper logs and Prusa captures given together.
    #[error("{paths}: Klipper logs (gzip) and Prusa captures (text) mixed: give one kind")]
    Mixed {
        /// The paths' name.
        paths: &'static str,
    },
    /// A trial for a path not among the inputs.
    #[error("{trial}: {path} is not one of the {paths} logs")]
    TrialNotGiven {
        /// The trials' name.
        trial: &'static str,
        /// The trial's path as written (escaped).
        path: String,
        /// The paths' name.
        paths: &'static str,
    },
    /// Kinematics given with Klipper logs, which carry theirs.
    #[error("{kinematics} goes with Prusa captures: a Klipper log carries its printer.kinematics")]
    KinematicsWithKlipper {
        /// The kinematics' name.
        kinematics: &'static str,
    },
    /// A trial given with Prusa captures, which carry theirs in `M973`.
    #[error("{trial} goes with Klipper logs (LOG.json.gz); Prusa captures carry their trial in M973")]
    TrialWithPrusa {
        /// The trials' name.
        trial: &'static str,
    },
    /// A Klipper log of a motor with other electrical periods per revolution than the profile.
    #[error(
        "{file}: full_steps_per_rotation {full_steps} is {periods} electrical periods per revolution, the profile's pole pairs {pole_pairs}: a wrong {motor} or {axis}"
    )]
    PeriodsPerRev {
        /// The log.
        file: String,
        /// Its `full_steps_per_rotation`.
        full_steps: u32,
        /// Its electrical periods per revolution (full steps / 4).
        periods: u32,
        /// The profile's pole pairs.
        pole_pairs: u32,
        /// The motor's name.
        motor: &'static str,
        /// The axis' name.
        axis: &'static str,
    },
    /// A Prusa capture of the other axis.
    #[error("{file}:{line}: `{gcode}` moved the other axis than {axis}")]
    OtherAxis {
        /// The file.
        file: String,
        /// The capture's line.
        line: u64,
        /// The G-code as echoed.
        gcode: String,
        /// The axis' name.
        axis: &'static str,
    },
    /// No capture in the Prusa files.
    #[error("no captures in the logs given")]
    NoCaptures,
    /// No stretch of steady motion in the Klipper logs.
    #[error(
        "no stretch of steady motion in the Klipper logs (at least {MIN_SEGMENT_S} s between ramps, the first and last {SETTLE_S} s cut): move at constant speed or sweep slowly (docs/accelerometer.md#klippers-motion-analysis-logs)"
    )]
    NoStretch,
    /// A Klipper log could not be read.
    #[error(transparent)]
    Klipper(#[from] KlipperError),
    /// A Prusa file could not be read.
    #[error(transparent)]
    Prusa(#[from] ReadError),
    /// The fit failed.
    #[error(transparent)]
    Ripple(#[from] RippleError),
}

/// Whether `path` is a Klipper log: it starts with the gzip magic `1f 8b`, where Prusa
/// captures are text. A file that cannot be opened counts as text, whose reader names it.
pub fn is_klipper_log(path: &Path) -> bool {
    let mut magic = [0u8; 2];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == [0x1f, 0x8b]
}

/// Reads `paths`: Klipper logs (told apart by their gzip header) of `axis`'s stepper, each
/// with its trial from `trials` (by path, as given), checked against `periods_per_rev` (the
/// profile's pole pairs); or Prusa captures, refusing one of the other axis, a trial, and
/// files with no capture at all. A mix of the two kinds is refused. `names` name the
/// inputs in messages.
pub fn read(
    paths: &[PathBuf],
    axis: Axis,
    trials: &[(PathBuf, TrialShift)],
    periods_per_rev: u32,
    names: &Names,
) -> Result<Sources, SourcesError> {
    let kinds: Vec<bool> = paths.iter().map(|p| is_klipper_log(p)).collect();
    if kinds.iter().any(|&k| k) && !kinds.iter().all(|&k| k) {
        return Err(SourcesError::Mixed { paths: names.paths });
    }
    if kinds.first().copied().unwrap_or(false) {
        return read_klipper(paths, axis, trials, periods_per_rev, names).map(Sources::Klipper);
    }
    if !trials.is_empty() {
        return Err(SourcesError::TrialWithPrusa { trial: names.trial });
    }
    read_prusa(paths, axis, names).map(Sources::Prusa)
}

/// Every capture of the Prusa files `paths` (`M973`/`M974` output), refusing one that moved
/// the other axis than `axis`, or none at all (also `accel refine`'s reader).
pub fn read_prusa(paths: &[PathBuf], axis: Axis, names: &Names) -> Result<Vec<AccelCapture>, SourcesError> {
    let mut all = Vec::new();
    for path in paths {
        for c in crate::prusa::read_file(path)? {
            if let Some(g) = c.gcode
                && g.axis() != axis
            {
                let gcode = g.to_string();
                return Err(SourcesError::OtherAxis { file: c.source, line: c.line, gcode, axis: names.axis });
            }
            all.push(c);
        }
    }
    if all.is_empty() {
        return Err(SourcesError::NoCaptures);
    }
    Ok(all)
}

/// Every Klipper log with its trial, checked against the profile's periods per revolution.
fn read_klipper(
    paths: &[PathBuf],
    axis: Axis,
    trials: &[(PathBuf, TrialShift)],
    periods_per_rev: u32,
    names: &Names,
) -> Result<Vec<Log>, SourcesError> {
    if let Some((p, _)) = trials.iter().find(|(p, _)| !paths.contains(p)) {
        let path = printable(p.as_os_str().as_encoded_bytes(), MAX_NAME_CHARS);
        return Err(SourcesError::TrialNotGiven { trial: names.trial, path, paths: names.paths });
    }
    let mut logs = Vec::new();
    for path in paths {
        let trial = trials.iter().find(|(p, _)| p == path).map(|x| x.1);
        let log = crate::klipper::read_file(path, &KlipperOptions { axis, accelerometer: None, trial })?;
        if log.periods_per_rev() != periods_per_rev {
            return Err(SourcesError::PeriodsPerRev {
                periods: log.periods_per_rev(),
                full_steps: log.full_steps_per_rotation,
                file: log.source,
                pole_pairs: periods_per_rev,
                motor: names.motor,
                axis: names.axis,
            });
        }
        logs.push(log);
    }
    Ok(logs)
}

impl Sources {
    /// `"klipper"` or `"prusa"`.
    pub fn format(&self) -> &'static str {
        match self {
            Sources::Klipper(_) => "klipper",
            Sources::Prusa(_) => "prusa",
        }
    }

    /// The number of files (Klipper logs) or captures (Prusa) read.
    pub fn len(&self) -> usize {
        match self {
            Sources::Klipper(v) => v.len(),
            Sources::Prusa(v) => v.len(),
        }
    }

    /// Whether nothing was read (never, from [`read`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The size of the printed acceleration per belt acceleration for [`RippleOptions::sensor_gain`]:
    /// Prusa's projection ([`crate::prusa::sensor_gain`], `kinematics` cartesian when not
    /// given); 1 for Klipper logs, whose reader projects on the belt itself (`x + y` on
    /// CoreXY), and which refuse a `kinematics` (they carry theirs).
    pub fn sensor_gain(&self, kinematics: Option<Kinematics>, axis: Axis, names: &Names) -> Result<f64, SourcesError> {
        match (self, kinematics) {
            (Sources::Klipper(_), Some(_)) => Err(SourcesError::KinematicsWithKlipper { kinematics: names.kinematics }),
            (Sources::Klipper(_), None) => Ok(1.0),
            (Sources::Prusa(_), k) => Ok(crate::prusa::sensor_gain(k.unwrap_or(Kinematics::Cartesian), axis).abs()),
        }
    }

    /// The ripple fit ([`identify_ripple`]) of the Klipper logs' stretches of steady motion
    /// or of the Prusa captures; refuses Klipper logs without such a stretch.
    pub fn fit(&self, r: &Reconstruction, o: &RippleOptions) -> Result<RippleFit, SourcesError> {
        match self {
            Sources::Klipper(logs) => {
                let segments: Vec<_> = logs.iter().flat_map(Log::segments).collect();
                if segments.is_empty() {
                    return Err(SourcesError::NoStretch);
                }
                Ok(identify_ripple(&segments, r, o)?)
            }
            Sources::Prusa(captures) => Ok(identify_ripple(captures, r, o)?),
        }
    }

    /// The stretches of steady motion the fit takes from Klipper logs (0 for Prusa captures).
    pub fn stretches(&self) -> usize {
        match self {
            Sources::Klipper(logs) => logs.iter().map(|l| l.segments().len()).sum(),
            Sources::Prusa(_) => 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CLI: Names = Names {
        paths: "--accel",
        axis: "--axis",
        motor: "--motor",
        trial: "--klipper-trial",
        kinematics: "--kinematics",
    };

    /// A directory of one test's own, removed when dropped.
    struct Dir(PathBuf);

    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// A gzip-headed file and an empty text file in a directory of this test's own.
    fn files(test: &str) -> (Dir, PathBuf, PathBuf) {
        let dir = std::env::temp_dir().join(format!("stepdamp-accel-sources-{}-{test}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (gz, text) = (dir.join("LOG.json.gz"), dir.join("session.log"));
        std::fs::write(&gz, [0x1f, 0x8b, 0, 0]).unwrap();
        std::fs::write(&text, "").unwrap();
        (Dir(dir), gz, text)
    }

    fn err(paths: &[PathBuf], trials: &[(PathBuf, TrialShift)]) -> String {
        read(paths, Axis::X, trials, 50, &CLI).unwrap_err().to_string()
    }

    const TRIAL: TrialShift = TrialShift { harmonic: 4, amplitude_rad: 0.1, phase_rad: 0.0 };

    #[test]
    fn klipper_logs_and_prusa_captures_together_are_refused_naming_the_option() {
        let (_dir, gz, text) = files("mixed");
        assert_eq!(
            err(&[gz, text], &[]),
            "--accel: Klipper logs (gzip) and Prusa captures (text) mixed: give one kind"
        );
    }

    #[test]
    fn a_trial_for_a_log_not_given_or_with_prusa_captures_is_refused() {
        let (_dir, gz, text) = files("trials");
        let e = err(std::slice::from_ref(&gz), &[(PathBuf::from("other.json.gz"), TRIAL)]);
        assert_eq!(e, "--klipper-trial: other.json.gz is not one of the --accel logs");
        let e = err(std::slice::from_ref(&text), &[(text.clone(), TRIAL)]);
        assert!(e.starts_with("--klipper-trial goes with Klipper logs (LOG.json.gz)"), "{e}");
    }

    #[test]
    fn no_capture_at_all_is_refused() {
        let (_dir, _, text) = files("empty");
        let e = err(std::slice::from_ref(&text), &[]);
        assert!(e.starts_with(&format!("{}: no M973/M974 capture", text.display())) && !e.contains('\n'), "{e}");
        assert_eq!(err(&[], &[]), "no captures in the logs given");
    }
}
