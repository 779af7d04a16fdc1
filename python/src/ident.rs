//! `identify`: detent harmonics and friction from run logs, through the library's one entry
//! (`stepdamp_identify::from_logs::identify`, the CLI's too): the route is the library's
//! choice.

use crate::err;
use crate::profile::PyProfile;
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use stepdamp_identify::fit::Estimate;
use stepdamp_identify::from_logs::{IdentifyOptions, LogSource, Route, identify as identify_logs};
use stepdamp_identify::log::LogColumns;

/// A log as the Python wrapper passes it: a path, or a frame's columns as
/// `(name, [(column, float64 array)], [unused column names])`.
#[derive(FromPyObject)]
pub enum LogArg<'py> {
    /// A file (str or os.PathLike).
    #[pyo3(transparent)]
    Path(PathBuf),
    /// Columns in memory: the log's name in messages, the read columns (contiguous
    /// float64, borrowed, not copied), and the names of the columns not read.
    Frame(String, Vec<(String, PyReadonlyArray1<'py, f64>)>, Vec<String>),
}

/// The library's source for one argument, borrowing the arrays' memory.
fn source<'a>(arg: &'a LogArg<'_>) -> PyResult<LogSource<'a>> {
    Ok(match arg {
        LogArg::Path(p) => LogSource::Path(p.clone()),
        LogArg::Frame(name, cols, unused) => {
            let values = cols
                .iter()
                .map(|(c, a)| {
                    let v = a.as_slice().map_err(|_| err(format!("{name}: column '{c}' is not a contiguous array")))?;
                    Ok((c.clone(), v))
                })
                .collect::<PyResult<Vec<_>>>()?;
            LogSource::Columns { columns: LogColumns { values, unused: unused.clone() }, name: name.clone() }
        }
    })
}

fn estimate<'py>(py: Python<'py>, e: &Estimate) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("value", e.value)?;
    d.set_item("ci95", e.ci95)?;
    Ok(d)
}

/// Identifies the detent harmonics, `Fs`, `D` and `J` from run logs (the CLI's
/// `identify`). `logs` is a list of paths or `(name, columns, unused)` ([`LogArg`]): the
/// Python wrapper passes a DataFrame's columns as arrays, which the library's reader checks
/// as it checks a file's rows, copying only the columns it uses.
/// The route is the CLI's: logs without `theta_fb_rad` take the sensorless route (which
/// also trims `R`), a set of both routes is refused; `sensorless=True` or `False` forces
/// one. Returns `(profile, report)`: `base` with the identified values, and the fit report
/// (`report["route"]` says which route ran).
#[pyfunction]
#[pyo3(signature = (logs, base, orders = vec![1, 2, 4], name = None, sensorless = None))]
pub fn identify<'py>(
    py: Python<'py>,
    logs: Vec<LogArg<'py>>,
    base: &PyProfile,
    orders: Vec<u16>,
    name: Option<String>,
    sensorless: Option<bool>,
) -> PyResult<(PyProfile, Bound<'py, PyDict>)> {
    let base = base.inner.clone();
    let sources = logs.iter().map(source).collect::<PyResult<Vec<_>>>()?;
    let report = py
        .allow_threads(|| -> Result<_, String> {
            let o = IdentifyOptions {
                route: sensorless.map(|s| if s { Route::Sensorless } else { Route::Encoder }),
                name,
                ..IdentifyOptions::new(&orders)
            };
            identify_logs(&sources, &base, &o).map_err(|e| e.to_string())
        })
        .map_err(err)?;
    let f = report.fit();
    let r = PyDict::new(py);
    let mut harmonics = Vec::new();
    for h in &f.harmonics {
        let d = PyDict::new(py);
        d.set_item("order", h.order)?;
        d.set_item("amplitude_nm", estimate(py, &h.amplitude_nm)?)?;
        d.set_item("phase_rad", estimate(py, &h.phase_rad)?)?;
        harmonics.push(d);
    }
    r.set_item("harmonics", harmonics)?;
    r.set_item("coulomb_friction_nm", estimate(py, &f.coulomb_friction_nm)?)?;
    r.set_item("viscous_nm_s_per_rad", f.viscous_nm_s_per_rad.as_ref().map(|e| estimate(py, e)).transpose()?)?;
    r.set_item("viscous_used_nm_s_per_rad", f.viscous_used)?;
    r.set_item("offset_nm", f.offset_nm.as_ref().map(|e| estimate(py, e)).transpose()?)?;
    r.set_item("inertia_kg_m2", f.inertia_kg_m2.as_ref().map(|e| estimate(py, e)).transpose()?)?;
    r.set_item("inertia_used_kg_m2", f.inertia_used)?;
    r.set_item("residual_rms_nm", f.residual_rms_nm)?;
    r.set_item("ripple_rms_nm", f.ripple_rms_nm)?;
    r.set_item("samples_used", f.samples_used)?;
    r.set_item("condition", f.condition)?;
    r.set_item("warnings", f.warnings.iter().map(ToString::to_string).collect::<Vec<_>>())?;
    let mut runs = Vec::new();
    for s in &f.runs {
        let d = PyDict::new(py);
        d.set_item("source", &s.source)?;
        d.set_item("mean_speed_rad_s", s.mean_speed_rad_s)?;
        d.set_item("duration_s", s.duration_s)?;
        d.set_item("electrical_periods", s.electrical_periods)?;
        d.set_item("samples_used", s.samples_used)?;
        d.set_item("samples", s.samples)?;
        d.set_item("inertial_share", s.inertial_share)?;
        d.set_item("back_step_fraction", s.back_step_fraction)?;
        runs.push(d);
    }
    r.set_item("runs", runs)?;
    let ignored: Vec<(String, Vec<String>)> =
        report.logs.iter().map(|l| (l.source.clone(), l.ignored_columns.clone())).collect();
    r.set_item("ignored_columns", ignored)?;
    r.set_item("route", report.route.name())?;
    if let (Some(r_ohm), Some(offset)) = (report.resistance_ohm(), report.current_offset_a) {
        r.set_item("resistance_ohm", r_ohm)?;
        r.set_item("current_offset_a", offset)?;
    }
    Ok((PyProfile { inner: report.profile }, r))
}
