//! `prusa_refine`: the CLI's `accel refine` (docs/accelerometer.md#refining-from-captures),
//! one influence step on Prusa's `M971` table from `M973` captures, through the same library
//! call (`stepdamp_export::prusa::refine::prusa_refine`). Translation only.

use crate::accel::{NAMES, PathsArg, axis_of, run_current, run_current_named};
use crate::cancel::interruptible;
use crate::err;
use crate::profile::PyProfile;
use pyo3::prelude::*;
use pyo3::types::{PyComplex, PyDict};
use std::path::PathBuf;
use stepdamp_accel::Axis;
use stepdamp_accel::refine::{InfluenceSource, RefineOptions, Refined, Timing};
use stepdamp_accel::ripple::MM_PER_REV_RANGE;
use stepdamp_accel::sources;
use stepdamp_export::prusa::Firmware;
use stepdamp_export::prusa::refine::{Request, Session, prusa_refine as refine_table, table_in_use};

fn step_dict<'py>(py: Python<'py>, r: &Refined) -> PyResult<Bound<'py, PyDict>> {
    let complex = |z: stepdamp_accel::Complex| PyComplex::from_doubles(py, z.re, z.im);
    let d = PyDict::new(py);
    d.set_item("harmonic", r.harmonic)?;
    d.set_item("direction", if r.phase_direction > 0.0 { "forward" } else { "backward" })?;
    d.set_item("speed_rev_s", r.speed_rev_s)?;
    d.set_item("baseline_m_s2", complex(r.baseline.value))?;
    d.set_item("baseline_radius95_m_s2", r.baseline.radius95)?;
    let (trial, carried) = match r.source {
        InfluenceSource::Trial(t) => (Some((complex(t.value), t.radius95)), None),
        InfluenceSource::Carried { current_ratio } => (None, Some(current_ratio)),
    };
    d.set_item("trial_m_s2", trial.as_ref().map(|t| t.0.clone()))?;
    d.set_item("trial_radius95_m_s2", trial.map(|t| t.1))?;
    d.set_item("carried_current_ratio", carried)?;
    d.set_item("influence_m_s2_per_rad", complex(r.influence.coefficient))?;
    d.set_item("influence_radius95_m_s2_per_rad", r.influence.coefficient_radius95)?;
    d.set_item("in_use", r.in_use)?;
    d.set_item("item", r.item)?;
    d.set_item("item_radius95", r.item_radius95)?;
    d.set_item("expected_residual95_m_s2", r.expected_residual95)?;
    Ok(d)
}

/// `accel refine`: the `M971` table that cancels what Prusa `M973` captures measured.
///
/// `paths`: the session logs (each capture's G-code echoed by the host). `motor`: the profile
/// (its pole pairs, name and `drive.current_limit_a`). `axis`: `"X"` or `"Y"`. The run current:
/// `current_peak_a` or `current_rms_a`. `in_use`: the file of the table loaded while recording
/// (`M971` lines), `None` for none. `influence_from`: an earlier session's logs (with its
/// trials) whose influence a harmonic without a trial here takes, times the ratio of the
/// currents, its current `influence_current_peak_a` or `influence_current_rms_a`
/// (docs/accelerometer.md#a-step-without-a-trial). `timing`: `"planned"` or `"markers"`.
///
/// Returns `steps` (per harmonic and direction: `harmonic`, `direction`, `speed_rev_s`,
/// `baseline_m_s2` and `trial_m_s2` (complex; `trial_m_s2` `None` when carried) with their 95 %
/// radii, `carried_current_ratio` (`None` with a trial), `influence_m_s2_per_rad` (complex) and
/// its radius, `in_use` and `item` (`(mag, pha)` table items), `item_radius95` (table units),
/// `expected_residual95_m_s2`), `text`
/// (what the CLI prints for them) and `gcode` (the file it writes, byte for byte). A table past
/// the firmware's int8 shifts raises the CLI's error, with the current where it would fit.
#[pyfunction]
#[pyo3(signature = (paths, motor, axis, *, current_peak_a = None, current_rms_a = None, in_use = None,
    influence_from = None, influence_current_peak_a = None, influence_current_rms_a = None, mm_per_rev = 32.0,
    periods_per_block = 20, timing = "planned"))]
#[allow(clippy::too_many_arguments)]
pub fn prusa_refine<'py>(
    py: Python<'py>,
    paths: PathsArg,
    motor: &PyProfile,
    axis: &str,
    current_peak_a: Option<f64>,
    current_rms_a: Option<f64>,
    in_use: Option<PathBuf>,
    influence_from: Option<PathsArg>,
    influence_current_peak_a: Option<f64>,
    influence_current_rms_a: Option<f64>,
    mm_per_rev: f64,
    periods_per_block: u32,
    timing: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let paths = paths.into_vec();
    let a = axis_of(axis)?;
    let letter = if a == Axis::X { 'X' } else { 'Y' };
    let run = run_current(current_peak_a, current_rms_a)?;
    let influence_given = influence_current_peak_a.is_some() || influence_current_rms_a.is_some();
    let earlier = match (influence_from, influence_given) {
        (None, false) => None,
        (None, true) => {
            return Err(err("influence_current_peak_a/_rms_a without influence_from: whose current is it?"));
        }
        (Some(p), _) => {
            let names = ("influence_current_peak_a", "influence_current_rms_a");
            Some((p.into_vec(), run_current_named(influence_current_peak_a, influence_current_rms_a, names)?))
        }
    };
    let (lo, hi) = MM_PER_REV_RANGE;
    if !(mm_per_rev.is_finite() && (lo..=hi).contains(&mm_per_rev)) {
        return Err(err(format!(
            "mm_per_rev {mm_per_rev}: must be in {lo}..={hi} mm (a pulley pitch radius of 1-50 mm)"
        )));
    }
    let timing = match timing {
        "planned" => Timing::Planned,
        "markers" => Timing::Markers,
        o => return Err(err(format!("timing {o:?}: \"planned\" or \"markers\""))),
    };
    let profile = motor.inner.clone();
    let options = RefineOptions {
        periods_per_rev: u32::from(profile.motor.pole_pairs),
        mm_per_rev,
        periods_per_block,
        scale: Firmware::V6_3_1.scale(),
        timing,
    };
    let (refined, text, gcode) = interruptible(py, move |_| -> Result<_, String> {
        let captures = sources::read_prusa(&paths, a, &NAMES).map_err(|e| e.to_string())?;
        let earlier_captures = match &earlier {
            Some((p, _)) => sources::read_prusa(p, a, &NAMES).map_err(|e| e.to_string())?,
            None => Vec::new(),
        };
        let request = Request {
            options,
            in_use: table_in_use(in_use.as_deref(), letter).map_err(|e| format!("in_use: {e}"))?,
            now: Session { captures: &captures, run },
            earlier: earlier.as_ref().map(|(_, then)| Session { captures: &earlier_captures, run: *then }),
            axis: letter,
            profile_name: &profile.name,
            current_limit_a: profile.drive.current_limit_a,
        };
        let refined = refine_table(&request).map_err(|e| e.to_string())?;
        let gcode = refined.gcode(&request).map_err(|e| e.to_string())?;
        Ok((refined.steps.clone(), refined.to_string(), gcode))
    })?;
    let d = PyDict::new(py);
    d.set_item("steps", refined.iter().map(|r| step_dict(py, r)).collect::<PyResult<Vec<_>>>()?)?;
    d.set_item("text", text)?;
    d.set_item("gcode", gcode)?;
    Ok(d)
}
