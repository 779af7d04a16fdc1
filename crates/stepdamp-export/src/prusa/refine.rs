//! `accel refine`'s whole step, for the command line and Python alike
//! (docs/accelerometer.md#refining-from-captures): the table in use read, the captures
//! refined by `stepdamp_accel::refine` (with an earlier session's influence where a harmonic
//! has no trial: docs/accelerometer.md#a-step-without-a-trial), the new table written as
//! `M971` lines and read back, or refused past the firmware's int8 shifts with the run current
//! where it would fit (docs/accelerometer.md#when-the-table-is-too-small).

use super::headroom::whole_ma_rms_at_or_above;
use super::measured::{MeasuredTable, TableVsCurrent};
use super::{Firmware, Fitted, PrusaCorrection, SHIFT_LIMIT, Spectrum, gcode};
use crate::{ExportError, RunCurrent};
use std::fmt;
use stepdamp_accel::AccelCapture;
use stepdamp_accel::refine::{
    Earlier, InUse, InfluenceSource, RefineOptions, Refined, current_ratio, refine, refine_with,
};

/// The table in use while captures were recorded: the `M971` lines of the file at `path`
/// (what `export prusa` wrote, or the printer's `M972` read-back) for `axis`, or an empty
/// table (`None`). Refuses a 6.2 (`M973`) table: the captures need firmware ≥ 6.3.1.
pub fn table_in_use(path: Option<&std::path::Path>, axis: char) -> Result<PrusaCorrection, ExportError> {
    let Some(path) = path else {
        let zero = Spectrum::default();
        return Ok(PrusaCorrection { forward: zero, backward: zero, firmware: Firmware::V6_3_1 });
    };
    let what = crate::escape::line(&path.display().to_string());
    let bytes = super::read::read_capped(path)?;
    let text = String::from_utf8(bytes)
        .map_err(|_| ExportError::Parse { what: what.clone(), reason: "not UTF-8 text".into() })?;
    let (c, _) = super::parse_text(&text, Some(axis), &what)?;
    if c.firmware != Firmware::V6_3_1 {
        return Err(ExportError::Invalid(format!(
            "{what}: an M973 (6.2) table; the captures need firmware >= 6.3.1, whose table is M971 lines"
        )));
    }
    Ok(c)
}

/// Captures recorded at one run current.
#[derive(Debug, Clone, Copy)]
pub struct Session<'a> {
    /// The captures (`M973`, each with its G-code).
    pub captures: &'a [AccelCapture],
    /// The run current they were recorded at.
    pub run: RunCurrent,
}

/// What a refinement is given.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    /// The refinement's choices (pole pairs, belt, block length, scale, timing).
    pub options: RefineOptions,
    /// The table in use while `now` was recorded ([`table_in_use`]).
    pub in_use: PrusaCorrection,
    /// This session.
    pub now: Session<'a>,
    /// An earlier session whose influences the harmonics `now` has no trial for take.
    pub earlier: Option<Session<'a>>,
    /// The axis letter of the `M971` lines (`X` or `Y`).
    pub axis: char,
    /// The profile's name, for the G-code's header.
    pub profile_name: &'a str,
    /// The highest run current the advice may name (A peak: the profile's
    /// `drive.current_limit_a`; the run current where that is higher).
    pub current_limit_a: f64,
}

/// A refined table.
#[derive(Debug, Clone)]
pub struct PrusaRefined {
    /// Each harmonic and direction's step.
    pub steps: Vec<Refined>,
    /// The earlier session's capture count and run current, and `I/I_earlier`, when given.
    pub earlier: Option<(usize, RunCurrent, f64)>,
    /// The run current of the session.
    pub run: RunCurrent,
    /// The new table: the table in use with each step's item (it may not fit the firmware:
    /// [`PrusaRefined::gcode`] says).
    pub table: PrusaCorrection,
}

impl PrusaRefined {
    /// The new table's `M971` lines for `r`'s axis and profile (read back to [`Self::table`]
    /// before they are returned), or the refusal of a table past the firmware's int8 shifts
    /// with the run current where it would fit, up to `r.current_limit_a`.
    pub fn gcode(&self, r: &Request<'_>) -> Result<String, ExportError> {
        write_table(&self.table, r)
    }
}

/// Refines `r.now` into a new table ([module docs](self)); [`PrusaRefined::gcode`] writes it.
pub fn prusa_refine(r: &Request<'_>) -> Result<PrusaRefined, ExportError> {
    let spectra = |s: &Spectrum| std::array::from_fn(|n| (f64::from(s.mag[n]), f64::from(s.pha[n])));
    let in_use = InUse { forward: spectra(&r.in_use.forward), backward: spectra(&r.in_use.backward) };
    let invalid = |e: stepdamp_accel::influence::InfluenceError| ExportError::Invalid(e.to_string());
    let (steps, earlier) = match r.earlier {
        None => (refine(r.now.captures, &r.options, &in_use).map_err(invalid)?, None),
        Some(then) => {
            let ratio = current_ratio(r.now.run.peak_a(), then.run.peak_a()).map_err(invalid)?;
            // The coefficients do not depend on the table that was in use then.
            let earlier_steps = refine(then.captures, &r.options, &InUse::default())
                .map_err(|e| ExportError::Invalid(format!("the earlier session: {e}")))?;
            let e = Earlier { steps: &earlier_steps, current_ratio: ratio };
            let steps = refine_with(r.now.captures, &r.options, &in_use, Some(&e)).map_err(invalid)?;
            (steps, Some((then.captures.len(), then.run, ratio)))
        }
    };
    let mut table = r.in_use;
    for s in &steps {
        let spectrum = if s.phase_direction > 0.0 { &mut table.forward } else { &mut table.backward };
        let n = s.harmonic as usize;
        spectrum.mag[n] = gcode::quantize(s.item.0, gcode::MAG_DECIMALS);
        spectrum.pha[n] = gcode::quantize(s.item.1, gcode::PHA_DECIMALS);
    }
    Ok(PrusaRefined { steps, earlier, run: r.now.run, table })
}

/// The G-code of `c`, refused when its table would not fit the firmware's int8 shifts, with
/// the run current at which it would (`measured`, from this one table: exact for a detent, an
/// estimate where the ripple grows with the current) up to `r.current_limit_a`.
fn write_table(c: &PrusaCorrection, r: &Request<'_>) -> Result<String, ExportError> {
    let (run, axis) = (r.now.run, r.axis);
    let peaks = [c.forward, c.backward].map(|s| s.peak_shift(c.firmware));
    let peak = peaks.iter().try_fold(0, |m, p| p.map(|p| p.max(m)));
    let Some(peak) = peak.filter(|&p| p <= SHIFT_LIMIT) else {
        let needs = match peak {
            Some(p) => format!("needs a shift of {p} of 4096"),
            None => "overflows the firmware's 32-bit sum".to_string(),
        };
        let measured = MeasuredTable { peak_a: run.peak_a(), table: *c };
        let up_to = r.current_limit_a.max(run.peak_a());
        let limit = "the profile's drive.current_limit_a, or the run current where that is higher";
        let advice = match TableVsCurrent::fit(&[measured])?.lowest_fitting_current_a(up_to)? {
            Some(from) => match whole_ma_rms_at_or_above(from, up_to)? {
                Some(at) => format!(
                    "with a shift that falls as 1/I (a detent's: exact for one; the part of the ripple that grows with \
                     the current moves it either way) the table would fit from {at} (`M906 {axis}{:.0}`, in mA RMS): \
                     record the plan again at that current (whether the motor may run that hot is yours to check) and \
                     refine from those captures",
                    1e3 * at.rms_a()
                ),
                None => format!(
                    "with a shift that falls as 1/I it would fit from {from:.4} A peak, but no whole mA of RMS from \
                     there is within {up_to:.3} A peak ({limit})"
                ),
            },
            None => {
                format!("no run current up to {up_to:.3} A peak ({limit}) makes it fit with a shift that falls as 1/I")
            }
        };
        return Err(ExportError::Invalid(format!(
            "the refined table {needs} at {run}, past Prusa's int8 shifts (±{SHIFT_LIMIT} of 4096, ±0.195 rad): the \
             ripple is too large for the table at this run current; {advice} \
             (docs/accelerometer.md#when-the-table-is-too-small)"
        )));
    };
    let fitted = Fitted { correction: *c, kept: 1.0, peak_shift: peak, wanted_peak_shift: peak as f64 };
    let text = gcode::write(&fitted, axis, &gcode::Header { profile: r.profile_name, current: run })?;
    let (back, _) = super::parse_text(&text, Some(axis), "the refined G-code")?;
    if back != *c {
        return Err(ExportError::Invalid("internal: the refined G-code reads back to another table".into()));
    }
    Ok(text)
}

impl fmt::Display for PrusaRefined {
    /// The earlier session's line (when given), then two lines per step: the responses, and
    /// the influence, the item before and after and the residual the linear model expects.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some((n, then, ratio)) = self.earlier {
            writeln!(f, "earlier session: {n} captures at {then}; its influences carried ×{ratio:.4} to {}", self.run)?;
        }
        for r in &self.steps {
            let dir = if r.phase_direction > 0.0 { "forward" } else { "backward" };
            let (b, i) = (&r.baseline, &r.influence);
            let how = match r.source {
                InfluenceSource::Trial(t) => format!("with the trial {:.4} ± {:.4} m/s²", t.value.abs(), t.radius95),
                InfluenceSource::Carried { current_ratio } => {
                    format!("no trial: the earlier session's influence ×{current_ratio:.4}")
                }
            };
            writeln!(
                f,
                "harmonic {:>2} {dir:<8} at {:+.2} rev/s: baseline {:.4} ± {:.4} m/s², {how}",
                r.harmonic,
                r.speed_rev_s,
                b.value.abs(),
                b.radius95,
            )?;
            writeln!(
                f,
                "  influence {:.3e} ± {:.1e} m/s² per rad; item ({:.5}, {:+.4}) -> ({:.5} ± {:.5}, {:+.4}); expected \
                 residual within {:.4} m/s²",
                i.coefficient.abs(),
                i.coefficient_radius95,
                r.in_use.0,
                r.in_use.1,
                r.item.0,
                r.item_radius95,
                r.item.1,
                r.expected_residual95
            )?;
        }
        Ok(())
    }
}
