//! Python bindings of stepdamp (`stepdamp._native`). Translation only: every number comes
//! from a library crate (`stepdamp-sim`, `stepdamp-identify`, `stepdamp-study`); this
//! crate converts arguments, releases the GIL around the Rust work, and turns Rust errors
//! into `stepdamp.StepdampError` with the same one-line message.

mod ident;
mod profile;
mod sim;
mod study;

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

create_exception!(
    _native,
    StepdampError,
    PyValueError,
    "An error reported by stepdamp's Rust code (same message as the CLI's)."
);

/// A Rust error as a Python exception, with its one-line message.
pub(crate) fn err(e: impl std::fmt::Display) -> PyErr {
    StepdampError::new_err(e.to_string())
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("StepdampError", m.py().get_type::<StepdampError>())?;
    m.add("PRESETS", stepdamp_sim::PRESETS.to_vec())?;
    // The run shape's defaults, from their one home (stepdamp_sim::RunSpec).
    m.add("DURATION_S", stepdamp_sim::RunSpec::DURATION_S)?;
    m.add("DWELL_S", stepdamp_sim::RunSpec::DWELL_S)?;
    m.add("RAMP_S", stepdamp_sim::RunSpec::RAMP_S)?;
    m.add_class::<profile::PyProfile>()?;
    m.add_function(wrap_pyfunction!(sim::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(sim::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(sim::linear_grid, m)?)?;
    m.add_function(wrap_pyfunction!(sim::resonance, m)?)?;
    m.add_function(wrap_pyfunction!(ident::identify, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_load, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_info, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_run_range, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_summarize, m)?)?;
    Ok(())
}
