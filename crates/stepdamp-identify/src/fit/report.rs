//! What `stepdamp identify` prints after a fit: the table, the decisions and the validation.

use super::Fit;
use crate::model::Model;
use crate::validation::{Validation, default_max_order, validate};
use serde::Serialize;
use std::fmt;

/// The report of a fit: the fit (its per-sample data left out of the JSON), the base
/// profile's name, and the fit's validation up to [`default_max_order`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitReport {
    /// Name of the base profile the fit started from.
    pub base: String,
    /// The fit.
    pub fit: Fit,
    /// Its validation ([`crate::validation::validate`]).
    pub validation: Validation,
    /// For logs recorded with a feed-forward running (`identify --ff-on`): what is left.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feed_forward: Option<FeedForwardCheck>,
    /// The flux linkage's shape from the logs' back-EMF runs ([`crate::emf`]), when there
    /// were any: the detent above was fitted with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flux: Option<crate::emf::FluxFit>,
    /// Why the flux shape was not measured, when the logs have no back-EMF run: what the
    /// fit then knows about the ripple that grows with the current.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flux_note: Option<String>,
}

/// What logs recorded with a detent feed-forward running tell (`identify --ff-on`, the
/// patent's criterion): the periodic effort ripple the fit still finds, against the ripple
/// the feed-forward carried. Both RMS over the electrical angle, in N·m.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeedForwardCheck {
    /// Name of the profile whose feed-forward ran.
    pub base: String,
    /// RMS in N·m of the ripple left with the feed-forward on: the difference between the
    /// model fitted to these logs and the one that ran.
    pub remaining_ripple_nm: f64,
    /// RMS in N·m of the ripple the feed-forward carried (the base profile's detent model).
    pub carried_ripple_nm: f64,
}

impl FeedForwardCheck {
    /// The check of `ff_on`, fitted to logs recorded with `base`'s feed-forward running.
    pub fn new(base: &stepdamp_profile::Profile, ff_on: &Fit) -> Self {
        let carried = Model::of_profile(base);
        FeedForwardCheck {
            base: base.name.clone(),
            remaining_ripple_nm: Model::from_fit(ff_on).ripple_difference_rms_nm(&carried),
            carried_ripple_nm: carried.ripple_rms_nm(),
        }
    }
}

impl fmt::Display for FeedForwardCheck {
    /// One line, in mN·m.
    fn fmt(&self, s: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            s,
            "feed-forward on: remaining ripple {:.3} mN·m RMS (the feed-forward of {} carried {:.3} mN·m RMS)",
            1e3 * self.remaining_ripple_nm,
            self.base,
            1e3 * self.carried_ripple_nm
        )
    }
}

impl FitReport {
    /// The report of `fit`, validated up to [`default_max_order`].
    pub fn new(base: &str, fit: Fit) -> Self {
        let validation = validate(&fit, default_max_order(&fit));
        FitReport { base: base.to_string(), fit, validation, feed_forward: None, flux: None, flux_note: None }
    }

    /// The report with the flux section fitted to the back-EMF runs.
    pub fn with_flux(mut self, flux: Option<crate::emf::FluxFit>) -> Self {
        self.flux = flux;
        self
    }

    /// The report with a note on the flux shape (see [`FitReport::flux_note`]).
    pub fn with_flux_note(mut self, note: Option<String>) -> Self {
        self.flux_note = note;
        self
    }

    /// The report with the feed-forward check of `--ff-on` logs.
    pub fn with_feed_forward(mut self, check: FeedForwardCheck) -> Self {
        self.feed_forward = Some(check);
        self
    }
}

impl fmt::Display for FitReport {
    /// The table (harmonics, friction, `J`, residual, runs), the warnings, the decisions
    /// and the validation, one item a line (amplitudes and torques in mN·m; 95 % intervals).
    fn fmt(&self, s: &mut fmt::Formatter<'_>) -> fmt::Result {
        let f = &self.fit;
        writeln!(s, "identified from {} samples (base {}); 95 % intervals", f.samples_used, self.base)?;
        writeln!(s, "  order   amplitude mN·m       phase rad")?;
        for h in &f.harmonics {
            writeln!(
                s,
                "  {:>5}   {:8.3} ± {:<7.3}   {:+8.4} ± {:.4}",
                h.order,
                1e3 * h.amplitude_nm.value,
                1e3 * h.amplitude_nm.ci95,
                h.phase_rad.value,
                h.phase_rad.ci95
            )?;
        }
        let fs = f.coulomb_friction_nm;
        writeln!(s, "  Fs   {:8.3} ± {:.3} mN·m", 1e3 * fs.value, 1e3 * fs.ci95)?;
        match f.viscous_nm_s_per_rad {
            Some(d) => writeln!(s, "  D    {:.4e} ± {:.1e} N·m·s/rad", d.value, d.ci95)?,
            None => writeln!(s, "  D    {:.4e} N·m·s/rad (not separable: kept)", f.viscous_used)?,
        }
        match f.inertia_kg_m2 {
            Some(j) => {
                writeln!(s, "  J    {:.4e} ± {:.1e} kg·m² (written to the profile's inertia_kg_m2)", j.value, j.ci95)?
            }
            None => writeln!(s, "  J    {:.4e} kg·m² (held: the base profile's)", f.inertia_used)?,
        }
        if let Some(c) = f.offset_nm {
            writeln!(
                s,
                "  constant torque {:.3} ± {:.3} mN·m (load or current offset; not in the profile)",
                1e3 * c.value,
                1e3 * c.ci95
            )?;
        }
        writeln!(
            s,
            "  residual {:.3} mN·m RMS (fitted detent ripple {:.3} mN·m RMS)",
            1e3 * f.residual_rms_nm,
            1e3 * f.ripple_rms_nm
        )?;
        for r in &f.runs {
            writeln!(
                s,
                "  run {}: {:+.4} rad/s, {:.1} electrical periods, {}/{} samples, J·dω/dt share {:.2}",
                r.source, r.mean_speed_rad_s, r.electrical_periods, r.samples_used, r.samples, r.inertial_share
            )?;
        }
        for w in &f.warnings {
            writeln!(s, "warning: {w}")?;
        }
        for d in &f.decisions {
            writeln!(s, "{d}")?;
        }
        write!(s, "validation (orders 1–{}):\n{}", self.validation.max_order, self.validation)?;
        if let Some(c) = &self.feed_forward {
            write!(s, "\n{c}")?;
        }
        if let Some(flux) = &self.flux {
            write!(s, "\n{}", flux.to_string().trim_end())?;
        }
        if let Some(note) = &self.flux_note {
            write!(s, "\nnote: {note}")?;
        }
        Ok(())
    }
}
