//! The Klipper + Trinamic accelerometer route (docs/accelerometer.md#refining-a-trinamic-table):
//! `klipper_plan` (the moves to log), `klipper_trial_table` (the trial table's block) and
//! `klipper_refine` (one influence step on the driver's table), as the CLI's `accel
//! klipper-plan`, `klipper-trial` and `klipper-refine`. Translation only: the plan is
//! `stepdamp_accel::klipper::plan`'s, the tables, step and blocks `stepdamp_export::tmc`'s.

use crate::accel::PathsArg;
use crate::cancel::interruptible;
use crate::err;
use crate::profile::PyProfile;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::HashMap;
use std::path::PathBuf;
use stepdamp_accel::Axis;
use stepdamp_accel::klipper::plan::{KlipperPlanOptions, plan_klipper};
use stepdamp_accel::klipper::table_step::PairStep;
use stepdamp_accel::klipper::{Kinematics, TrialShift};
use stepdamp_accel::sources::{self, Sources};
use stepdamp_export::tmc::{self, ShiftTable};

use crate::accel::NAMES;

/// `kinematics` as Python passes it: `"cartesian"` or `"corexy"`.
pub(crate) fn kinematics_of(name: &str) -> PyResult<Kinematics> {
    Kinematics::from_name(name)
        .ok_or_else(|| err(format!("kinematics \"{}\": cartesian or corexy", stepdamp_export::escape::line(name))))
}

/// The motor of a driver section (`"tmc5160 stepper_x"`), checked as the CLI checks it.
fn motor_of(section: &str) -> PyResult<Axis> {
    let s = tmc::klipper_section(section).map_err(err)?;
    match s.split_once(' ').map(|x| x.1) {
        Some("stepper_x") => Ok(Axis::X),
        Some("stepper_y") => Ok(Axis::Y),
        _ => Err(err(format!(
            "axis \"{}\": the logs are read for stepper_x or stepper_y (on CoreXY the A and B motors)",
            stepdamp_export::escape::line(section)
        ))),
    }
}

/// The moves to log for the table step, as the CLI's `accel klipper-plan` prints them.
///
/// `axis`: the driver section (`"tmc5160 stepper_x"`). `kinematics`: `"cartesian"` or
/// `"corexy"`. `rotation_distance`: mm per motor revolution. Returns `moves` (each `dx_mm`,
/// `dy_mm`, `feed_mm_min`, `motor_revs`, `kept_s`) and `gcode`, the text the CLI prints.
#[pyfunction]
#[pyo3(signature = (axis, kinematics, rotation_distance, *, travel_mm = 100.0, speed_rev_s = 2.0,
    accel_mm_s2 = 1000.0, steady_s = 3.0))]
#[allow(clippy::too_many_arguments)]
pub fn klipper_plan<'py>(
    py: Python<'py>,
    axis: &str,
    kinematics: &str,
    rotation_distance: f64,
    travel_mm: f64,
    speed_rev_s: f64,
    accel_mm_s2: f64,
    steady_s: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let motor = motor_of(axis)?;
    let kinematics = kinematics_of(kinematics)?;
    let o = KlipperPlanOptions {
        rotation_distance_mm: rotation_distance,
        travel_mm,
        speed_rev_s,
        accel_mm_s2,
        steady_s,
        ..KlipperPlanOptions::new(kinematics, motor)
    };
    let plan = plan_klipper(&o).map_err(err)?;
    let moves = plan
        .moves
        .iter()
        .map(|m| {
            let d = PyDict::new(py);
            d.set_item("dx_mm", m.dx_mm)?;
            d.set_item("dy_mm", m.dy_mm)?;
            d.set_item("feed_mm_min", m.feed_mm_min)?;
            d.set_item("motor_revs", m.motor_revs)?;
            d.set_item("kept_s", m.kept_s)?;
            Ok(d)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let d = PyDict::new(py);
    d.set_item("moves", moves)?;
    d.set_item("gcode", plan.to_string())?;
    Ok(d)
}

/// What a shift table does: `harmonic`, `shift_rad` (asked), `achieved_rad`, `stray_rad`.
fn table_dict<'py>(py: Python<'py>, t: &ShiftTable) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("harmonic", t.harmonic)?;
    d.set_item("shift_rad", t.shift_rad)?;
    d.set_item("achieved_rad", t.achieved_rad)?;
    d.set_item("stray_rad", t.stray_rad)?;
    Ok(d)
}

/// The trial table the CLI's `accel klipper-trial` writes: the dict of what it does
/// (`harmonic`, `shift_rad`, `achieved_rad`, `stray_rad`), `klipper_trial` (the `(H, U, PHI)`
/// to pass as that log's trial, as the CLI prints it: `"4,0.1201,0"`) and `block`, the file
/// the CLI writes, byte for byte.
#[pyfunction]
#[pyo3(signature = (axis, *, harmonic = 4, shift_rad = 0.12))]
pub fn klipper_trial_table<'py>(
    py: Python<'py>,
    axis: &str,
    harmonic: u16,
    shift_rad: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let t = ShiftTable::trial(harmonic, shift_rad).map_err(err)?;
    let d = table_dict(py, &t)?;
    d.set_item("klipper_trial", t.klipper_trial_arg())?;
    d.set_item("block", tmc::trial_block(&t, axis).map_err(err)?)?;
    Ok(d)
}

/// One pair of the step: `direction`, `speed_rev_s`, the responses (m/s², complex) and their
/// 95 % radii, the influence (m/s² per rad), the expected response and the floor.
fn pair_dict<'py>(py: Python<'py>, p: &PairStep) -> PyResult<Bound<'py, PyDict>> {
    let c = |z: stepdamp_accel::Complex| pyo3::types::PyComplex::from_doubles(py, z.re, z.im);
    let d = PyDict::new(py);
    d.set_item("direction", p.direction.name())?;
    d.set_item("speed_rev_s", p.speed_rev_s)?;
    d.set_item("baseline_m_s2", c(p.baseline.value))?;
    d.set_item("baseline_radius95_m_s2", p.baseline.radius95)?;
    d.set_item("trial_m_s2", c(p.trial.value))?;
    d.set_item("trial_radius95_m_s2", p.trial.radius95)?;
    d.set_item("influence_m_s2_per_rad", c(p.coefficient))?;
    d.set_item("influence_radius95_m_s2_per_rad", p.coefficient_radius95)?;
    d.set_item("predicted_m_s2", c(p.predicted))?;
    d.set_item("floor_m_s2", p.floor_m_s2)?;
    Ok(d)
}

/// One influence step on a Trinamic driver's wave table from Klipper logs, as the CLI's
/// `accel klipper-refine`.
///
/// `paths`: the logs recorded with the table in use and with the trial table. `klipper_trials`:
/// `{path: (H, U, PHI)}` for the trial logs (as `klipper_trial_table` gives it). `motor`: the
/// profile whose pole pairs the logs are checked against. `axis`: the driver section
/// (`"tmc5160 stepper_x"`). `in_use`: the table in use's block file, `None` for Klipper's
/// default table. Returns `harmonic`, `in_use_rad`, `trial_rad`, `new_rad`,
/// `new_radius95_rad` (rad), `pairs` (per direction and speed), `table` (what the new table
/// does), `text` (the report the CLI prints) and `block` (the file it writes, byte for byte).
#[pyfunction]
#[pyo3(signature = (paths, motor, axis, *, klipper_trials, in_use = None, periods_per_block = 20))]
pub fn klipper_refine<'py>(
    py: Python<'py>,
    paths: PathsArg,
    motor: &PyProfile,
    axis: &str,
    klipper_trials: HashMap<PathBuf, (u32, f64, f64)>,
    in_use: Option<PathBuf>,
    periods_per_block: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let paths = paths.into_vec();
    let motor_axis = motor_of(axis)?;
    let trials: Vec<(PathBuf, TrialShift)> = klipper_trials
        .into_iter()
        .map(|(p, (harmonic, amplitude_rad, phase_rad))| (p, TrialShift { harmonic, amplitude_rad, phase_rad }))
        .collect();
    if let Some((_, t)) = trials.first() {
        tmc::check_order(t.harmonic).map_err(|e| err(format!("klipper_trials: {e}")))?;
    }
    let pole_pairs = u32::from(motor.inner.motor.pole_pairs);
    let axis_name = axis.to_string();
    let r = interruptible(py, move |_| -> Result<_, String> {
        let logs = match sources::read(&paths, motor_axis, &trials, pole_pairs, &NAMES).map_err(|e| e.to_string())? {
            Sources::Klipper(logs) => logs,
            Sources::Prusa(_) => return Err("paths: Prusa captures; klipper_refine reads Klipper's logs".into()),
        };
        let used = tmc::table_in_use(in_use.as_deref()).map_err(|e| e.to_string())?;
        tmc::klipper_refine(&logs, &used, &axis_name, periods_per_block).map_err(|e| e.to_string())
    })?;
    let s = &r.step;
    let d = PyDict::new(py);
    d.set_item("harmonic", s.harmonic)?;
    d.set_item("in_use_rad", s.in_use_rad)?;
    d.set_item("trial_rad", s.trial_rad)?;
    d.set_item("new_rad", s.new_rad)?;
    d.set_item("new_radius95_rad", s.new_radius95_rad)?;
    d.set_item("pairs", s.pairs.iter().map(|p| pair_dict(py, p)).collect::<PyResult<Vec<_>>>()?)?;
    d.set_item("table", table_dict(py, &r.table)?)?;
    d.set_item("text", s.to_string())?;
    d.set_item("block", r.block)?;
    Ok(d)
}
