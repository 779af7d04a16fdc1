//! Tolerance studies (`stepdamp-study`): load a spec, run a range of variants, summarise.
//! A study travels between processes as its JSON text.

use crate::cancel::interruptible;
use crate::err;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::HashMap;
use stepdamp_study::{Study, Table};

fn parse(json: &str) -> PyResult<Study> {
    Study::from_json(json).map_err(err)
}

/// Reads and checks a study spec file; returns the study as JSON.
#[pyfunction]
pub fn study_load(path: std::path::PathBuf) -> PyResult<String> {
    Study::load(&path).map(|s| s.to_json()).map_err(err)
}

/// Parses and checks spec TOML text (`origin` names it in errors, `base_dir` resolves a
/// relative motor path); returns the study as JSON.
#[pyfunction]
#[pyo3(signature = (text, origin = "<string>", base_dir = "."))]
pub fn study_from_toml(text: &str, origin: &str, base_dir: &str) -> PyResult<String> {
    Study::from_toml_str(text, origin, std::path::Path::new(base_dir)).map(|s| s.to_json()).map_err(err)
}

/// `(variants, columns)` of a study.
#[pyfunction]
pub fn study_info(json: &str) -> PyResult<(u64, Vec<String>)> {
    let s = parse(json)?;
    Ok((s.spec.variants, s.columns()))
}

/// Runs variants `start..stop` on all cores (GIL released; Ctrl-C stops it,
/// [`interruptible`]); returns the rows as a dict of
/// numpy columns, in variant order.
#[pyfunction]
pub fn study_run_range<'py>(py: Python<'py>, json: &str, start: u64, stop: u64) -> PyResult<Bound<'py, PyDict>> {
    let s = parse(json)?;
    let t = interruptible(py, |stopped| s.run_range_until(start, stop, &|| {}, stopped))?;
    let d = PyDict::new(py);
    for (j, name) in t.columns.iter().enumerate() {
        d.set_item(name, PyArray1::from_vec(py, t.rows.iter().map(|r| r[j]).collect()))?;
    }
    Ok(d)
}

/// Summarises a results table (columns by name, any row order). Returns
/// `(summary JSON, printed report)`.
#[pyfunction]
pub fn study_summarize(json: &str, columns: HashMap<String, Vec<f64>>) -> PyResult<(String, String)> {
    let s = parse(json)?;
    let names = s.columns();
    let mut cols = Vec::with_capacity(names.len());
    for n in &names {
        cols.push(columns.get(n).ok_or_else(|| err(format!("results table: missing column '{n}'")))?);
    }
    let rows = cols.first().map_or(0, |c| c.len());
    if cols.iter().any(|c| c.len() != rows) {
        return Err(err("results table: columns of different lengths"));
    }
    let table = Table { columns: names, rows: (0..rows).map(|i| cols.iter().map(|c| c[i]).collect()).collect() };
    let sum = s.summarize(&table).map_err(err)?;
    Ok((sum.to_json(), sum.report()))
}
