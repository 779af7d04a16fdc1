//! The accelerometer route (docs/accelerometer.md): `read_accel_captures` reads Prusa
//! `M973`/`M974` captures or a Klipper motion-analysis log as the library does
//! (`stepdamp_accel::prusa`, `stepdamp_accel::klipper`), and `identify_accel` identifies
//! the head and the motor's ripple per direction (`stepdamp_accel::ripple::identify_ripple`,
//! the CLI's `identify --accel`): both read and fit through `stepdamp_accel::sources` and
//! write the file with `stepdamp_accel::ripple::file`. Translation only: every number is the
//! library's.

use crate::cancel::interruptible;
use crate::err;
use crate::profile::PyProfile;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::HashMap;
use std::f64::consts::TAU;
use std::ops::Range;
use std::path::PathBuf;
use stepdamp_accel::klipper::{KlipperOptions, Log, TrialShift};
use stepdamp_accel::ripple::file::RippleFile;
use stepdamp_accel::ripple::{Direction, Interval95, MM_PER_REV_RANGE, RippleCapture, RippleFit, RippleOptions};
use stepdamp_accel::sources::{self, Names, SourcesError};
use stepdamp_accel::{AccelCapture, Axis, Commanded, Reconstruction};
use stepdamp_export::model::RunCurrent;
use stepdamp_export::prusa::Firmware;

/// A trial as Python gives it: `(H, U, PHI)`, the order, the shift's amplitude (rad) and
/// phase (rad) of `U·sin(H·θe + PHI)`.
type TrialArg = (u32, f64, f64);

/// `X` or `Y` (either case): the motor the captures moved (on CoreXY the A or B motor).
pub(crate) fn axis_of(s: &str) -> PyResult<Axis> {
    match s {
        "X" | "x" => Ok(Axis::X),
        "Y" | "y" => Ok(Axis::Y),
        // Quoted as Rust's Debug writes it: control characters escaped, on one line.
        o => Err(err(format!("axis {o:?}: Prusa phase stepping has axes X and Y"))),
    }
}

/// `'X'` or `'Y'`.
fn axis_letter(a: Axis) -> char {
    if a == Axis::X { 'X' } else { 'Y' }
}

fn trial_shift((harmonic, amplitude_rad, phase_rad): TrialArg) -> TrialShift {
    TrialShift { harmonic, amplitude_rad, phase_rad }
}

fn array<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    // The Vec becomes the array's buffer: no copy per sample.
    PyArray1::from_vec(py, v)
}

/// The commanded motion's columns: `t_s` (the sample's time: planned, or Klipper's print
/// time), `theta_e_rad`, `speed_rev_s`, `accel_rev_s2`, `motor_rev`.
fn commanded_columns<'py>(py: Python<'py>, d: &Bound<'py, PyDict>, c: &[Commanded]) -> PyResult<()> {
    let col = |f: fn(&Commanded) -> f64| array(py, c.iter().map(f).collect());
    d.set_item("t_s", col(|x| x.t_s))?;
    d.set_item("theta_e_rad", col(|x| x.electrical_rad))?;
    d.set_item("speed_rev_s", col(|x| x.speed_rev_s))?;
    d.set_item("accel_rev_s2", col(|x| x.accel_rev_s2))?;
    d.set_item("motor_rev", col(|x| x.motor_rev))?;
    Ok(())
}

/// One Prusa capture as a dict (see `read_accel_captures`).
fn prusa_dict<'py>(
    py: Python<'py>,
    c: AccelCapture,
    commanded: Option<Vec<Commanded>>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("format", "prusa")?;
    d.set_item("source", &c.source)?;
    d.set_item("line", c.line)?;
    d.set_item("gcode", c.gcode.map(|g| g.to_string()))?;
    d.set_item("axis", c.gcode.map(|g| axis_letter(g.axis()).to_string()))?;
    let direction = c.gcode.map(|g| if g.phase_direction() > 0.0 { Direction::Forward } else { Direction::Backward });
    d.set_item("direction", direction.map(Direction::name))?;
    let a = &c.annotations;
    d.set_item("sampling_freq_hz", a.sampling_freq_hz)?;
    let n = PyDict::new(py);
    n.set_item("sampling_freq_hz", a.sampling_freq_hz)?;
    n.set_item("movement_ok", a.movement_ok)?;
    n.set_item("accel_error", a.accel_error)?;
    n.set_item("start_marker_s", a.times.start_marker)?;
    n.set_item("end_marker_s", a.times.end_marker)?;
    n.set_item("signal_start_s", a.times.signal_start)?;
    n.set_item("signal_end_s", a.times.signal_end)?;
    n.set_item("valid", a.is_valid())?;
    d.set_item("annotations", n)?;
    match commanded {
        Some(cmd) => commanded_columns(py, &d, &cmd)?,
        None => {
            for k in ["t_s", "theta_e_rad", "speed_rev_s", "accel_rev_s2", "motor_rev"] {
                d.set_item(k, py.None())?;
            }
        }
    }
    d.set_item("accel_m_s2", array(py, c.samples))?;
    Ok(d)
}

/// A Klipper log's stretch: its samples, direction, and mean rate (Hz).
struct Stretch {
    range: Range<usize>,
    direction: Direction,
    rate_hz: f64,
}

/// The stretches of `log` as the library cuts them ([`Log::segments`]).
fn stretches(log: &Log) -> Vec<Stretch> {
    log.segments()
        .iter()
        .map(|s| Stretch { range: s.range.clone(), direction: s.direction, rate_hz: s.sampling_freq_hz() })
        .collect()
}

/// What a Klipper log says about itself, for each of its stretches' dicts.
fn klipper_log_dict<'py>(py: Python<'py>, log: &Log) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("source", &log.source)?;
    d.set_item("stepper", &log.stepper)?;
    d.set_item("accelerometer", &log.accelerometer)?;
    d.set_item("kinematics", log.kinematics.name())?;
    d.set_item("microsteps", log.microsteps)?;
    d.set_item("full_steps_per_rotation", log.full_steps_per_rotation)?;
    d.set_item("periods_per_rev", log.periods_per_rev())?;
    d.set_item("mcu_phase_offset", log.mcu_phase_offset)?;
    d.set_item("trial", log.trial.map(|t| (t.harmonic, t.amplitude_rad, t.phase_rad)))?;
    d.set_item("samples", log.times_s.len())?;
    d.set_item("steps", log.steps)?;
    d.set_item("records", log.records)?;
    d.set_item("skipped_records", log.skipped_records)?;
    d.set_item("accel_errors", log.accel_errors)?;
    d.set_item("accel_overflows", log.accel_overflows)?;
    Ok(d)
}

/// One stretch of a Klipper log as a dict (see `read_accel_captures`).
fn klipper_dict<'py>(
    py: Python<'py>,
    log: &Log,
    info: &Bound<'py, PyDict>,
    s: &Stretch,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let r = s.range.clone();
    d.set_item("format", "klipper")?;
    d.set_item("source", &log.source)?;
    d.set_item("range", (r.start, r.end))?;
    d.set_item("direction", s.direction.name())?;
    d.set_item("sampling_freq_hz", s.rate_hz)?;
    d.set_item("log", info)?;
    commanded_columns(py, &d, &log.commanded[r.clone()])?;
    d.set_item("accel_m_s2", array(py, log.accel_m_s2[r].to_vec()))?;
    Ok(d)
}

/// What one file held: Prusa captures (with their commanded motion when the G-code is
/// known) or a Klipper log and its stretches.
enum FileRead {
    Prusa(Vec<(AccelCapture, Option<Vec<Commanded>>)>),
    Klipper(Box<Log>, Vec<Stretch>),
}

/// The accelerometer captures of one file, as the CLI's `identify --accel` reads them
/// (docs/accelerometer.md), read with the GIL released.
///
/// A Prusa session log (`M973`/`M974` output as a host logged it): every capture in order,
/// with the commanded motion of those whose G-code the log echoed, rebuilt as the CLI does
/// (electrical angle 0 at the first settle block, sample 0 at planned time 0) with
/// `periods_per_rev` (the profile's pole pairs) and `mm_per_rev` (belt travel per motor
/// revolution, mm). A Klipper motion-analysis log (`LOG.json.gz`, told apart by its gzip
/// header): the stretches of steady motion of `axis`'s stepper (`"X"` or `"Y"`; on CoreXY the
/// A or B motor) as the library cuts them for the ripple fit, dated and angled by the log;
/// `trial` is the `(H, U, PHI)` shift `U·sin(H·θe + PHI)` (rad) the driver's table carried.
///
/// Returns a list of dicts, one per capture or stretch: `format` (`"prusa"`, `"klipper"`),
/// `source`, `direction` (`"forward"`, `"backward"`), `sampling_freq_hz` (Hz; a stretch's
/// mean rate), and float64 arrays `accel_m_s2` (m/s² on the motor's belt), `t_s` (s: the
/// planned time, or Klipper's print time), `theta_e_rad` (the commanded electrical angle,
/// rad, not wrapped), `speed_rev_s` (rev/s), `accel_rev_s2` (rev/s²), signed like the angle,
/// and `motor_rev` (revolutions); the commanded arrays and `direction` are `None` for a Prusa
/// capture whose G-code is unknown. Prusa captures add `line`, `gcode`, `axis` and
/// `annotations` (the printed `sampling_freq_hz`, `movement_ok`, `accel_error`, the marker
/// and signal times `start_marker_s`, `end_marker_s`, `signal_start_s`, `signal_end_s`, and
/// `valid`, the firmware's own check); Klipper stretches add `range` (their samples
/// `(start, stop)` in the log) and `log` (its stepper, accelerometer, kinematics,
/// microsteps, …). Errors are the library's one-line messages naming the file and the line
/// or record.
#[pyfunction]
#[pyo3(signature = (path, *, axis = "X", periods_per_rev = 50, mm_per_rev = 32.0, trial = None))]
pub fn read_accel_captures<'py>(
    py: Python<'py>,
    path: PathBuf,
    axis: &str,
    periods_per_rev: u32,
    mm_per_rev: f64,
    trial: Option<TrialArg>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let axis = axis_of(axis)?;
    let r = Reconstruction { periods_per_rev, start_angle_rad: 0.0, first_sample_s: 0.0, mm_per_rev };
    let read = interruptible(py, move |_| -> Result<FileRead, String> {
        if sources::is_klipper_log(&path) {
            let o = KlipperOptions { axis, accelerometer: None, trial: trial.map(trial_shift) };
            let log = stepdamp_accel::klipper::read_file(&path, &o).map_err(|e| e.to_string())?;
            let s = stretches(&log);
            return Ok(FileRead::Klipper(Box::new(log), s));
        }
        if trial.is_some() {
            return Err(SourcesError::TrialWithPrusa { trial: "trial" }.to_string());
        }
        let captures = stepdamp_accel::prusa::read_file(&path).map_err(|e| e.to_string())?;
        let with_motion = captures
            .into_iter()
            .map(|c| {
                let cmd = c.gcode.map(|_| c.commanded(&r)).transpose().map_err(|e| e.to_string())?;
                Ok((c, cmd))
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(FileRead::Prusa(with_motion))
    })?;
    match read {
        FileRead::Prusa(v) => v.into_iter().map(|(c, cmd)| prusa_dict(py, c, cmd)).collect(),
        FileRead::Klipper(log, s) => {
            let info = klipper_log_dict(py, &log)?;
            s.iter().map(|s| klipper_dict(py, &log, &info, s)).collect()
        }
    }
}

/// The run current from the one of `current_peak_a`, `current_rms_a` given.
pub(crate) fn run_current(peak: Option<f64>, rms: Option<f64>) -> PyResult<RunCurrent> {
    run_current_named(peak, rms, ("current_peak_a", "current_rms_a"))
}

/// [`run_current`] with the two arguments' Python names.
pub(crate) fn run_current_named(
    peak: Option<f64>,
    rms: Option<f64>,
    (peak_name, rms_name): (&str, &str),
) -> PyResult<RunCurrent> {
    match (peak, rms) {
        // The library's check, the message in Python's names (the library names the CLI's options).
        (Some(p), None) => {
            RunCurrent::from_peak(p).map_err(|_| err(format!("{peak_name} {p}: must be finite and > 0 A")))
        }
        (None, Some(r)) => {
            RunCurrent::from_rms(r).map_err(|_| err(format!("{rms_name} {r}: must be finite and > 0 A")))
        }
        (Some(_), Some(_)) => Err(err(format!("{peak_name} and {rms_name}: one of the two, not both"))),
        (None, None) => Err(err(format!(
            "the run current is needed: {peak_name} (peak, the current vector) or {rms_name} (RMS per phase), one of the two"
        ))),
    }
}

/// Python's names of the inputs, in the library's messages.
pub(crate) const NAMES: Names =
    Names { paths: "paths", axis: "axis", motor: "motor", trial: "klipper_trials", kinematics: "kinematics" };

fn interval<'py>(py: Python<'py>, i: Interval95) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("value", i.value)?;
    d.set_item("low", i.low)?;
    d.set_item("high", i.high)?;
    Ok(d)
}

/// The library's [`RippleFit`] as a dict, field for field (intervals as `{value, low, high}`).
fn fit_dict<'py>(py: Python<'py>, f: &RippleFit) -> PyResult<Bound<'py, PyDict>> {
    let h = &f.head;
    let head = PyDict::new(py);
    head.set_item("total_inertia_kg_m2", interval(py, h.total_inertia_kg_m2)?)?;
    head.set_item("carriage_mass_kg", interval(py, h.carriage_mass_kg)?)?;
    head.set_item("belt_hz", interval(py, h.belt_hz)?)?;
    head.set_item("belt_damping_ratio", interval(py, h.belt_damping_ratio)?)?;
    head.set_item("belt_stiffness_n_per_m", h.belt_stiffness_n_per_m)?;
    head.set_item("rotor_damping_nm_s_per_rad", interval(py, h.rotor_damping_nm_s_per_rad)?)?;
    head.set_item("shift_delay_s", interval(py, h.shift_delay_s)?)?;
    head.set_item("sensor_gain", f.sensor_gain)?;
    head.set_item("sensor_sign_fitted", f.sensor_sign_fitted)?;
    let a = &f.axis;
    let axis = PyDict::new(py);
    axis.set_item("pulley_radius_m", a.pulley_radius_m)?;
    axis.set_item("total_inertia_kg_m2", a.total_inertia_kg_m2)?;
    axis.set_item("belt_omega_rad_s", a.belt_omega_rad_s)?;
    axis.set_item("belt_damping_ratio", a.belt_damping_ratio)?;
    axis.set_item("stiffness_nm_per_rad", a.stiffness_nm_per_rad)?;
    axis.set_item("viscous_nm_s_per_rad", a.viscous_nm_s_per_rad)?;
    let mut harmonics = Vec::new();
    for x in &f.harmonics {
        let d = PyDict::new(py);
        d.set_item("order", x.order)?;
        d.set_item("direction", x.direction.name())?;
        d.set_item("amplitude_nm", interval(py, x.amplitude_nm)?)?;
        d.set_item("phase_rad", interval(py, x.phase_rad)?)?;
        d.set_item("radius95_nm", x.radius95_nm)?;
        d.set_item("blocks", x.blocks)?;
        d.set_item("speeds_rev_s", x.speeds_rev_s)?;
        d.set_item("explained_share", x.explained_share)?;
        harmonics.push(d);
    }
    let mut missing = Vec::new();
    for x in &f.not_identified {
        let d = PyDict::new(py);
        d.set_item("order", x.order)?;
        d.set_item("direction", x.direction.name())?;
        d.set_item("blocks", x.blocks)?;
        d.set_item("band_limit_rev_s", x.band_limit_rev_s)?;
        d.set_item("reason", &x.reason)?;
        missing.push(d);
    }
    let d = PyDict::new(py);
    d.set_item("head", head)?;
    d.set_item("axis_model", axis)?;
    d.set_item("harmonics", harmonics)?;
    d.set_item("not_identified", missing)?;
    d.set_item("explained_share", f.explained_share)?;
    d.set_item("blocks", f.blocks)?;
    d.set_item("captures", f.captures)?;
    d.set_item("text", f.to_string())?;
    Ok(d)
}

/// Paths as Python gives them: one, or a list.
#[derive(FromPyObject)]
pub(crate) enum PathsArg {
    /// One file (str or os.PathLike).
    #[pyo3(transparent)]
    One(PathBuf),
    /// Several.
    #[pyo3(transparent)]
    Many(Vec<PathBuf>),
}

impl PathsArg {
    /// The paths, in order.
    pub(crate) fn into_vec(self) -> Vec<PathBuf> {
        match self {
            PathsArg::One(p) => vec![p],
            PathsArg::Many(v) => v,
        }
    }
}

/// The head and the motor's ripple in N·m per direction from accelerometer captures (the
/// CLI's `stepdamp identify --accel`; docs/accelerometer.md#identifying-the-ripple-from-captures).
///
/// `paths`: one or several Prusa session logs with the echoed `M973`/`M974` commands (an
/// `M974` sweep and an `M973` pair per direction, `identify plan --accel`), or Klipper
/// motion-analysis logs (gzip); one kind. `motor`: the base profile (Km, Nr, J, friction).
/// `axis`: `"X"` or `"Y"`. The run current: `current_peak_a` (the current vector) or
/// `current_rms_a` (per phase), A, one of the two. `mm_per_rev`: belt travel per motor
/// revolution, mm, in [`MM_PER_REV_RANGE`] (the pulley's pitch radius is this / 2π).
/// `periods_per_block`: electrical periods per lock-in block. `klipper_trials`: `{path: (H, U, PHI)}`, the shift
/// `U·sin(H·θe + PHI)` (rad) each Klipper log's driver table carried. `orders`: the orders
/// to identify (`None`: 1–16 where the sampling rate allows, the CLI's). `kinematics`:
/// `"cartesian"` or `"corexy"`, for Prusa captures (the firmware's projection; `None`:
/// cartesian); refused with Klipper logs, which carry theirs.
///
/// Returns the library's `RippleFit` as a dict: `head` (`total_inertia_kg_m2`,
/// `carriage_mass_kg`, `belt_hz`, `belt_damping_ratio`, `rotor_damping_nm_s_per_rad`,
/// `shift_delay_s`, each `{value, low, high}` with its 95 % interval, and
/// `belt_stiffness_n_per_m`, `sensor_gain`, `sensor_sign_fitted`), `axis_model` (the head's model at the estimates), `harmonics`
/// (per direction and order: `amplitude_nm` and `phase_rad` with intervals, torque on the
/// rotor `−A·sin(k·θe + φ)`; `radius95_nm`, `blocks`, `speeds_rev_s`, `explained_share`),
/// `not_identified` (with `reason`), the validation `explained_share`, `blocks`, `captures`;
/// and `format` (`"prusa"`, `"klipper"`), `motor`, `axis`, `current_peak_a`, `text`, the
/// report the CLI prints, and `toml`, the file the CLI writes (docs/files.md#identified-ripple-toml),
/// byte for byte. Errors are the library's one-line messages the CLI prints, naming these
/// arguments (`paths`, `axis`, `motor`, `klipper_trials`).
#[pyfunction]
#[pyo3(signature = (paths, motor, axis, *, current_peak_a = None, current_rms_a = None, mm_per_rev = 32.0,
    periods_per_block = 4, klipper_trials = None, orders = None, kinematics = None))]
#[allow(clippy::too_many_arguments)]
pub fn identify_accel<'py>(
    py: Python<'py>,
    paths: PathsArg,
    motor: &PyProfile,
    axis: &str,
    current_peak_a: Option<f64>,
    current_rms_a: Option<f64>,
    mm_per_rev: f64,
    periods_per_block: u32,
    klipper_trials: Option<HashMap<PathBuf, TrialArg>>,
    orders: Option<Vec<u32>>,
    kinematics: Option<&str>,
) -> PyResult<Bound<'py, PyDict>> {
    let paths = paths.into_vec();
    let klipper_trials: Vec<(PathBuf, TrialShift)> =
        klipper_trials.unwrap_or_default().into_iter().map(|(p, t)| (p, trial_shift(t))).collect();
    let axis = axis_of(axis)?;
    let run = run_current(current_peak_a, current_rms_a)?;
    let (lo, hi) = MM_PER_REV_RANGE;
    if !(mm_per_rev.is_finite() && (lo..=hi).contains(&mm_per_rev)) {
        return Err(err(format!(
            "mm_per_rev {mm_per_rev}: must be in {lo}..={hi} mm (a pulley pitch radius of 1-50 mm)"
        )));
    }
    if paths.is_empty() {
        return Err(err("paths: no capture given"));
    }
    let kinematics = kinematics.map(crate::klipper::kinematics_of).transpose()?;
    let base = &motor.inner;
    let m = &base.motor;
    let defaults = RippleOptions::new(u32::from(m.pole_pairs), mm_per_rev * 1e-3 / TAU, run.peak_a());
    let mut o = RippleOptions {
        rotor_inertia_kg_m2: m.inertia_kg_m2,
        km_nm_per_a: m.km_nm_per_a,
        viscous_nm_s_per_rad: m.viscous_nm_s_per_rad,
        coulomb_friction_nm: m.coulomb_friction_nm,
        periods_per_block,
        trial_scale: Firmware::V6_3_1.scale(),
        orders: orders.unwrap_or_else(|| defaults.orders.clone()),
        ..defaults
    };
    let r =
        Reconstruction { periods_per_rev: o.periods_per_rev, start_angle_rad: 0.0, first_sample_s: 0.0, mm_per_rev };
    let (fit, format) = interruptible(py, |_| -> Result<_, String> {
        let s = sources::read(&paths, axis, &klipper_trials, o.periods_per_rev, &NAMES).map_err(|e| e.to_string())?;
        o.sensor_gain = s.sensor_gain(kinematics, axis, &NAMES).map_err(|e| e.to_string())?;
        Ok((s.fit(&r, &o).map_err(|e| e.to_string())?, s.format()))
    })?;
    let toml = RippleFile::new(&fit, &base.name, axis_letter(axis), run.peak_a()).to_toml_string().map_err(err)?;
    let d = fit_dict(py, &fit)?;
    d.set_item("format", format)?;
    d.set_item("toml", toml)?;
    d.set_item("motor", &base.name)?;
    d.set_item("axis", axis_letter(axis).to_string())?;
    d.set_item("current_peak_a", run.peak_a())?;
    Ok(d)
}
