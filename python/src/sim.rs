//! `simulate`, `sweep`, `linear_grid`, `resonance`.

use crate::cancel::interruptible;
use crate::err;
use crate::profile::PyProfile;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::ops::ControlFlow;
use stepdamp_core::Mode;
use stepdamp_sim::runlog::{FromRecord, LogRow, check_log_rows};
use stepdamp_sim::{
    ClosedLoop, Compensation, Profile, RunSpec, SimOptions, SweepSpec, SweepSummary, check_mode_compensation,
    check_same_hardware, run_while,
};

/// A mode by the core's name (`Mode::name`: `open-loop`, `servo`).
pub(crate) fn mode(s: &str) -> PyResult<Mode> {
    s.parse().map_err(|e| err(format!("mode '{s}': {e}")))
}

/// A compensation by the core's name (`Compensation::name`: `off`, `patent`, `estimated`,
/// `angle`, `table`).
pub(crate) fn compensation(s: &str) -> PyResult<Compensation> {
    s.parse().map_err(|e| err(format!("compensation '{s}': {e}")))
}

/// Simulation options; `substeps` `None` is the library's default (as the CLI's).
fn options(substeps: Option<u32>, current_noise_a: f64, seed: u64, load_torque_nm: f64) -> SimOptions {
    let d = SimOptions::default();
    SimOptions { substeps: substeps.unwrap_or(d.substeps), current_noise_a, seed, load_torque_nm, ..d }
}

/// The controller's profile: `controller` or the motor's own, checked for the same hardware.
fn controller_of(motor: &Profile, controller: Option<&PyProfile>) -> PyResult<Profile> {
    match controller {
        Some(c) => {
            check_same_hardware(motor, &motor.name, &c.inner, &c.inner.name).map_err(err)?;
            Ok(c.inner.clone())
        }
        None => Ok(motor.clone()),
    }
}

fn column<'py>(py: Python<'py>, d: &Bound<'py, PyDict>, name: &str, v: Vec<f64>) -> PyResult<()> {
    // The Vec becomes the array's buffer: one allocation per column, no copy per sample.
    d.set_item(name, PyArray1::from_vec(py, v))
}

/// One constant-speed run (the CLI's `simulate`). Returns `(log, metrics)`: the run-log
/// columns as numpy arrays (one row per control period) and the velocity-error metrics.
#[pyfunction]
#[pyo3(signature = (profile, mode = "open-loop", compensation = "patent", speed_rad_s = 10.0,
    duration_s = RunSpec::DURATION_S, *, controller = None, dwell_s = RunSpec::DWELL_S, ramp_s = RunSpec::RAMP_S, load_torque_nm = 0.0, current_noise_a = 0.0, substeps = None, seed = 1))]
#[allow(clippy::too_many_arguments)]
pub fn simulate<'py>(
    py: Python<'py>,
    profile: &PyProfile,
    mode: &str,
    compensation: &str,
    speed_rad_s: f64,
    duration_s: f64,
    controller: Option<PyRef<'py, PyProfile>>,
    dwell_s: f64,
    ramp_s: f64,
    load_torque_nm: f64,
    current_noise_a: f64,
    substeps: Option<u32>,
    seed: u64,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
    let motor = profile.inner.clone();
    let ctrl = controller_of(&motor, controller.as_deref())?;
    let (mode, comp) = (self::mode(mode)?, self::compensation(compensation)?);
    check_mode_compensation(mode, comp).map_err(err)?;
    let spec = RunSpec { dwell_s, ramp_s, ..RunSpec::for_duration(speed_rad_s, duration_s) };
    let pwm = motor.drive.pwm_hz;
    let nr = motor.motor.pole_pairs;
    spec.check(pwm, nr).map_err(err)?;
    let opts = options(substeps, current_noise_a, seed, load_torque_nm);
    // Bounded before the columns are allocated (the whole log is returned in memory).
    let n = check_log_rows(duration_s, pwm).map_err(err)?;
    let mut lp = ClosedLoop::new(&motor, &ctrl, mode, comp, &opts).map_err(err)?;
    let (cols, m) = interruptible(py, move |stop| -> Result<_, stepdamp_sim::SimError> {
        let mut cols: [Vec<f64>; 11] = std::array::from_fn(|_| Vec::with_capacity(n));
        let m = run_while(&mut lp, &spec, pwm, |k, rec| {
            let r = LogRow::from_record(k, pwm, nr, rec);
            for (c, v) in cols.iter_mut().zip([
                r.t_s,
                r.theta_cmd_rad,
                r.theta_fb_rad,
                r.omega_fb_rad_s,
                r.i_a_a,
                r.i_b_a,
                r.i_d_a,
                r.i_q_a,
                r.iq_cmd_a,
                r.v_a_v,
                r.v_b_v,
            ]) {
                c.push(v);
            }
            if stop() { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
        })?;
        Ok((cols, m))
    })?;
    let log = PyDict::new(py);
    let names = stepdamp_sim::runlog::LOG_COLUMNS;
    for (name, c) in names.into_iter().zip(cols) {
        column(py, &log, name, c)?;
    }
    let metrics = PyDict::new(py);
    metrics.set_item("vel_err_rms_rad_s", m.vel_err_rms_rad_s)?;
    metrics.set_item("vel_err_pp_rad_s", m.vel_err_pp_rad_s)?;
    metrics.set_item("lost_sync", m.lost_sync)?;
    metrics.set_item("max_load_angle_e_rad", m.max_load_angle_e_rad)?;
    Ok((log, metrics))
}

/// `points` speeds evenly spaced from `from_rad_s` to `to_rad_s` inclusive (the CLI's
/// `--from/--to/--points` grid), rad/s; more than `stepdamp_sim::MAX_POINTS` is an error.
#[pyfunction]
pub fn linear_grid(from_rad_s: f64, to_rad_s: f64, points: u64) -> PyResult<Vec<f64>> {
    let n = usize::try_from(points).unwrap_or(usize::MAX);
    stepdamp_sim::linear_grid(from_rad_s, to_rad_s, n).map_err(err)
}

/// Velocity error against speed (the CLI's `sweep`), in parallel on all cores. Returns
/// `(table, summary_json, summary_text)`: the sweep table's columns (docs/files.md) and the
/// library's `SweepSummary` as JSON (the CLI's `--format json`) and as the CLI's text.
#[pyfunction]
#[pyo3(signature = (profile, modes, compensations, speeds_rad_s, *, controller = None, duration_s = RunSpec::DURATION_S,
    load_torque_nm = 0.0, current_noise_a = 0.0, substeps = None, seed = 1))]
#[allow(clippy::too_many_arguments)]
pub fn sweep<'py>(
    py: Python<'py>,
    profile: &PyProfile,
    modes: Vec<String>,
    compensations: Vec<String>,
    speeds_rad_s: Vec<f64>,
    controller: Option<PyRef<'py, PyProfile>>,
    duration_s: f64,
    load_torque_nm: f64,
    current_noise_a: f64,
    substeps: Option<u32>,
    seed: u64,
) -> PyResult<(Bound<'py, PyDict>, String, String)> {
    let motor = profile.inner.clone();
    let ctrl = controller_of(&motor, controller.as_deref())?;
    let spec = SweepSpec {
        speeds_rad_s,
        modes: modes.iter().map(|m| mode(m)).collect::<PyResult<_>>()?,
        compensations: compensations.iter().map(|c| compensation(c)).collect::<PyResult<_>>()?,
        run: RunSpec::for_duration(1.0, duration_s),
        options: options(substeps, current_noise_a, seed, load_torque_nm),
        table: None,
    };
    let rows = interruptible(py, |stop| stepdamp_sim::sweep_until(&motor, &ctrl, &spec, &|| {}, stop))?;
    let t = PyDict::new(py);
    t.set_item("mode", rows.iter().map(|r| r.mode.name()).collect::<Vec<_>>())?;
    t.set_item("compensation", rows.iter().map(|r| r.compensation.name()).collect::<Vec<_>>())?;
    column(py, &t, "speed_cmd_rad_s", rows.iter().map(|r| r.speed_cmd_rad_s).collect())?;
    column(py, &t, "vel_err_rms_rad_s", rows.iter().map(|r| r.vel_err_rms_rad_s).collect())?;
    column(py, &t, "vel_err_pp_rad_s", rows.iter().map(|r| r.vel_err_pp_rad_s).collect())?;
    t.set_item("lost_sync", rows.iter().map(|r| r.lost_sync).collect::<Vec<_>>().into_pyarray(py))?;
    let summary = SweepSummary::new(&motor, &rows);
    let json = serde_json::to_string(&summary).map_err(err)?;
    Ok((t, json, summary.to_string()))
}

/// Natural frequency, damping and resonance speeds of a profile (the CLI's `resonance`):
/// a dict with `natural_frequency_rad_s`, `holding_stiffness_nm_per_rad`, `damping_ratio`,
/// and `resonances_rad_s` {order: speed} for `Profile::resonance_orders` (the detent
/// orders, highest first, or 4, 2, 1 when it has none).
#[pyfunction]
pub fn resonance<'py>(py: Python<'py>, profile: &PyProfile) -> PyResult<Bound<'py, PyDict>> {
    let p = &profile.inner;
    let d = PyDict::new(py);
    d.set_item("motor", &p.name)?;
    d.set_item("natural_frequency_rad_s", p.natural_frequency_rad_s())?;
    d.set_item("holding_stiffness_nm_per_rad", p.holding_stiffness_nm_per_rad())?;
    d.set_item("damping_ratio", p.damping_ratio())?;
    let r = PyDict::new(py);
    for k in p.resonance_orders() {
        r.set_item(k, p.resonance_speed_rad_s(k))?;
    }
    d.set_item("resonances_rad_s", r)?;
    Ok(d)
}
