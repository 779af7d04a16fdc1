//! `identify`: detent harmonics and friction from servo-mode run logs.

use crate::err;
use crate::profile::PyProfile;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use stepdamp_identify::fit::{Estimate, FitOptions, fit};
use stepdamp_identify::log::{LogOptions, RunLog, parse_log, read_log};
use stepdamp_identify::model::Model;
use stepdamp_identify::sensorless::flux::FluxOptions;
use stepdamp_identify::sensorless::log::{LogKind, SensorlessLog, log_kind, parse_sensorless_log, read_sensorless_log};
use stepdamp_identify::sensorless::{self, SensorlessFit};

/// The route a log calls for: sensorless when its header has no `theta_fb_rad`.
fn kind_of(kind: &str, a: &str) -> Result<LogKind, String> {
    match kind {
        "path" => log_kind(std::path::Path::new(a)).map_err(|e| e.to_string()),
        _ => {
            let header = a.lines().next().unwrap_or("");
            Ok(if header.split(',').any(|c| c.trim().trim_matches('"') == "theta_fb_rad") {
                LogKind::Encoder
            } else {
                LogKind::Sensorless
            })
        }
    }
}

/// Reads and fits sensorless logs (the CLI's sensorless route).
fn sensorless_fit(
    logs: &[(String, String, Option<String>)],
    base: &stepdamp_sim::Profile,
    orders: &[u16],
) -> Result<(SensorlessFit, Vec<SensorlessLog>), String> {
    let mut read = Vec::new();
    for (kind, a, b) in logs {
        read.push(match kind.as_str() {
            "path" => read_sensorless_log(std::path::Path::new(a)).map_err(|e| e.to_string())?,
            "csv" => {
                parse_sensorless_log(a.as_bytes(), b.as_deref().unwrap_or("<DataFrame>")).map_err(|e| e.to_string())?
            }
            _ => return Err(format!("log kind '{kind}': expected path or csv")),
        });
    }
    let fo = sensorless::fit_options(base, orders);
    let f = sensorless::identify(&read, base, &fo, &FluxOptions::default()).map_err(|e| e.to_string())?;
    Ok((f, read))
}

fn estimate<'py>(py: Python<'py>, e: &Estimate) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("value", e.value)?;
    d.set_item("ci95", e.ci95)?;
    Ok(d)
}

/// Identifies the detent harmonics, `Fs`, `D` and `J` from run logs (the CLI's
/// `identify`). `logs` is a list of `("path", path)` or `("csv", text, source)`
/// (the Python wrapper turns DataFrames into CSV text, so the CLI's reader checks them).
/// Logs without `theta_fb_rad` (or `sensorless=True`) take the sensorless route, as the
/// CLI's, which also trims `R`. Returns `(profile, report)`: `base` with the identified
/// values, and the fit report (`report["route"]` says which route ran).
#[pyfunction]
#[pyo3(signature = (logs, base, orders = vec![1, 2, 4], name = None, sensorless = None))]
pub fn identify<'py>(
    py: Python<'py>,
    logs: Vec<(String, String, Option<String>)>,
    base: &PyProfile,
    orders: Vec<u16>,
    name: Option<String>,
    sensorless: Option<bool>,
) -> PyResult<(PyProfile, Bound<'py, PyDict>)> {
    let base = base.inner.clone();
    let opts = LogOptions::new(base.motor.pole_pairs);
    type Routed = (stepdamp_identify::fit::Fit, Model, Vec<(String, Vec<String>)>, Option<(f64, (f64, f64))>);
    let (f, model, ignored, sensorless_found) = py
        .allow_threads(|| -> Result<Routed, String> {
            let first = logs.first().ok_or("no logs given")?;
            let route = match sensorless {
                Some(true) => LogKind::Sensorless,
                Some(false) => LogKind::Encoder,
                None => kind_of(&first.0, &first.1)?,
            };
            if route == LogKind::Sensorless {
                let (sf, read) = sensorless_fit(&logs, &base, &orders)?;
                let ignored = read.iter().map(|l| (l.source.clone(), l.ignored_columns.clone())).collect();
                let found = (sf.estimated.resistance_ohm, sf.estimated.current_offset_a);
                return Ok((sf.fit.clone(), sf.model(), ignored, Some(found)));
            }
            let mut read = Vec::new();
            for (kind, a, b) in &logs {
                let log: RunLog = match kind.as_str() {
                    "path" => read_log(std::path::Path::new(a), &opts).map_err(|e| e.to_string())?,
                    "csv" => parse_log(a.as_bytes(), b.as_deref().unwrap_or("<DataFrame>"), &opts)
                        .map_err(|e| e.to_string())?,
                    _ => return Err(format!("log kind '{kind}': expected path or csv")),
                };
                read.push(log);
            }
            let f = fit(&read, &FitOptions::for_profile(&base, &orders)).map_err(|e| e.to_string())?;
            let ignored = read.iter().map(|l| (l.source.clone(), l.ignored_columns.clone())).collect();
            let model = Model::from_fit(&f);
            Ok((f, model, ignored, None))
        })
        .map_err(err)?;
    let name = name.unwrap_or_else(|| format!("{}-identified", base.name));
    let profile = model.apply_to(&base, Some(&name), &name).map_err(err)?;
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
    r.set_item("ignored_columns", ignored)?;
    r.set_item("route", if sensorless_found.is_some() { "sensorless" } else { "encoder" })?;
    if let Some((r_ohm, offset)) = sensorless_found {
        r.set_item("resistance_ohm", r_ohm)?;
        r.set_item("current_offset_a", offset)?;
    }
    Ok((PyProfile { inner: profile }, r))
}
