//! Python bindings of stepdamp (`stepdamp._native`). Translation only: every number comes
//! from a library crate (`stepdamp-sim`, `stepdamp-identify`, `stepdamp-study`, `stepdamp-accel`); this
//! crate converts arguments, releases the GIL around the Rust work (which Ctrl-C stops:
//! `cancel`), and turns Rust errors into `stepdamp.StepdampError` with the same one-line
//! message.

mod accel;
mod cancel;
mod ident;
mod klipper;
mod profile;
mod prusa;
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
    // NumPy's C API is looked up now, once: looked up later, a pending KeyboardInterrupt
    // would make the lookup fail, and rust-numpy panics then.
    numpy::PyArray1::<f64>::zeros(m.py(), 0, false);
    m.add("PRESETS", stepdamp_sim::PRESETS.to_vec())?;
    // The most points of a speed grid and speeds of a sweep, from its one home.
    m.add("MAX_POINTS", stepdamp_sim::MAX_POINTS)?;
    // The run-log columns the readers use (docs/files.md#run-log-csv): the wrapper hands
    // these to Rust as arrays and any other column by name only.
    m.add("LOG_COLUMNS", stepdamp_identify::log::KNOWN_COLUMNS.to_vec())?;
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
    m.add_function(wrap_pyfunction!(accel::read_accel_captures, m)?)?;
    m.add_function(wrap_pyfunction!(accel::identify_accel, m)?)?;
    m.add_function(wrap_pyfunction!(prusa::prusa_refine, m)?)?;
    m.add_function(wrap_pyfunction!(klipper::klipper_plan, m)?)?;
    m.add_function(wrap_pyfunction!(klipper::klipper_trial_table, m)?)?;
    m.add_function(wrap_pyfunction!(klipper::klipper_refine, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_load, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_info, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_run_range, m)?)?;
    m.add_function(wrap_pyfunction!(study::study_summarize, m)?)?;
    Ok(())
}
