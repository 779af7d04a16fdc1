//! What `stepdamp identify run --refine` prints and summarises: [`RefinementReport`].

use super::{PERIODIC_ORDERS, Refinement};
use crate::fit::{Fit, Warning};
use crate::model::Model;
use serde::Serialize;
use stepdamp_profile::{DetentTerm, Profile};

/// One step of the refinement as printed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReportStep {
    /// 0: the feed-forward-off estimate; 1…: feed-forward-on corrections.
    pub iteration: usize,
    /// The estimate's detent harmonics after this step.
    pub detent: Vec<DetentTerm>,
    /// The estimate's Coulomb friction `Fs`, N·m.
    pub coulomb_friction_nm: f64,
    /// [`super::RefineStep::ripple_rms_nm`], N·m RMS on the fitted orders.
    pub ripple_rms_nm: f64,
    /// [`super::RefineStep::periodic_rms_nm`], N·m RMS on orders 1–[`PERIODIC_ORDERS`].
    pub periodic_rms_nm: f64,
}

/// One row of the summary (`refine-summary.csv`): a quantity's value in the simulated
/// motor (the truth), the feed-forward-off fit and the refined estimate. `None`: not
/// applicable (an empty CSV cell).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SummaryRow {
    /// `amplitude`, `phase` (one row per order), `coulomb_friction`, `viscous_friction`,
    /// `inertia`, `periodic_ripple_rms` (`identified` = before, feed-forward off;
    /// `refined` = after, the refined estimate fed forward), `ripple_reduction` (before /
    /// after, in `refined`).
    pub quantity: &'static str,
    /// Harmonic order (amplitude and phase rows).
    pub order: Option<u16>,
    /// Unit of the three values (`N·m`, `rad`, `N·m·s/rad`, `kg·m²`, `ratio`).
    pub unit: &'static str,
    /// The simulated motor's value.
    pub motor: Option<f64>,
    /// The feed-forward-off fit's value.
    pub identified: Option<f64>,
    /// The refined value.
    pub refined: Option<f64>,
}

/// The refinement of `identify run --refine`: the steps, the check run, the ripple before
/// and after, and the summary rows. `Display` is the table the CLI prints, `Serialize` its
/// JSON; the CLI writes [`RefinementReport::summary`] as `refine-summary.csv`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RefinementReport {
    /// Every step, the first being the starting estimate.
    pub steps: Vec<ReportStep>,
    /// [`super::RefineCheck::ripple_rms_nm`] of the check run, N·m.
    pub check_ripple_rms_nm: f64,
    /// [`super::RefineCheck::periodic_rms_nm`] of the check run, N·m.
    pub check_periodic_rms_nm: f64,
    /// Periodic ripple before (feed-forward off), N·m RMS ([`Refinement::ripple_before_after_nm`]).
    pub ripple_before_nm: f64,
    /// Periodic ripple after (the refined estimate fed forward), N·m RMS.
    pub ripple_after_nm: f64,
    /// `before / after` (after floored at 1e-15 N·m).
    pub ripple_reduction: f64,
    /// Warnings of the check run's (feed-forward-on) fit.
    pub warnings: Vec<Warning>,
    /// The summary rows (`refine-summary.csv`).
    pub summary: Vec<SummaryRow>,
}

impl RefinementReport {
    /// The report of `r`, refined from the feed-forward-off fit `f0` on logs simulated with
    /// `motor`.
    pub fn new(motor: &Profile, f0: &Fit, r: &Refinement) -> Self {
        let (before, after) = r.ripple_before_after_nm();
        let reduction = before / after.max(1e-15);
        RefinementReport {
            steps: r
                .steps
                .iter()
                .map(|s| ReportStep {
                    iteration: s.iteration,
                    detent: s.model.detent.clone(),
                    coulomb_friction_nm: s.model.coulomb_friction_nm,
                    ripple_rms_nm: s.ripple_rms_nm,
                    periodic_rms_nm: s.periodic_rms_nm,
                })
                .collect(),
            check_ripple_rms_nm: r.check.ripple_rms_nm,
            check_periodic_rms_nm: r.check.periodic_rms_nm,
            ripple_before_nm: before,
            ripple_after_nm: after,
            ripple_reduction: reduction,
            warnings: r.check.fit.warnings.clone(),
            summary: summary_rows(motor, f0, r, before, after, reduction),
        }
    }
}

fn summary_rows(motor: &Profile, f0: &Fit, r: &Refinement, before: f64, after: f64, reduction: f64) -> Vec<SummaryRow> {
    let mut rows = Vec::new();
    let mut row = |quantity, order, unit, motor, identified, refined| {
        rows.push(SummaryRow { quantity, order, unit, motor, identified, refined });
    };
    let start = Model::from_fit(f0);
    let find = |m: &Model, k: u16| m.detent.iter().find(|h| h.order == k).copied();
    let truth = Model::of_profile(motor);
    for h in &r.model.detent {
        let (t, i) = (find(&truth, h.order), find(&start, h.order));
        let amp = |h: Option<DetentTerm>| h.map(|h| h.amplitude_nm);
        row("amplitude", Some(h.order), "N·m", amp(t).or(Some(0.0)), amp(i), Some(h.amplitude_nm));
        row("phase", Some(h.order), "rad", t.map(|t| t.phase_rad), i.map(|i| i.phase_rad), Some(h.phase_rad));
    }
    let m = &motor.motor;
    let refined_j = r.model.inertia_kg_m2.unwrap_or(f0.inertia_used);
    let fs = (m.coulomb_friction_nm, start.coulomb_friction_nm, r.model.coulomb_friction_nm);
    row("coulomb_friction", None, "N·m", Some(fs.0), Some(fs.1), Some(fs.2));
    let d = (m.viscous_nm_s_per_rad, start.viscous_nm_s_per_rad, r.model.viscous_nm_s_per_rad);
    row("viscous_friction", None, "N·m·s/rad", Some(d.0), Some(d.1), Some(d.2));
    row("inertia", None, "kg·m²", Some(m.inertia_kg_m2), Some(f0.inertia_used), Some(refined_j));
    row("periodic_ripple_rms", None, "N·m", None, Some(before), Some(after));
    row("ripple_reduction", None, "ratio", None, None, Some(reduction));
    rows
}

impl std::fmt::Display for RefinementReport {
    /// Torques in mN·m, phases in rad.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "refinement with the feed-forward on (servo mode):")?;
        for st in &self.steps {
            let terms: Vec<String> = st
                .detent
                .iter()
                .map(|h| format!("k{} {:.3} mN·m {:+.4} rad", h.order, 1e3 * h.amplitude_nm, h.phase_rad))
                .collect();
            let on = if st.iteration == 0 {
                "feed-forward off".to_string()
            } else {
                format!("step {}'s estimate on", st.iteration - 1)
            };
            writeln!(
                f,
                "  step {}: ripple {:8.4} mN·m RMS on the fitted orders, {:8.4} on orders 1–{PERIODIC_ORDERS} ({on}); {}; Fs {:.3} mN·m",
                st.iteration,
                1e3 * st.ripple_rms_nm,
                1e3 * st.periodic_rms_nm,
                terms.join(", "),
                1e3 * st.coulomb_friction_nm
            )?;
        }
        writeln!(
            f,
            "  check, the refined estimate on: ripple {:8.4} mN·m RMS on the fitted orders, {:8.4} on orders 1–{PERIODIC_ORDERS}",
            1e3 * self.check_ripple_rms_nm,
            1e3 * self.check_periodic_rms_nm
        )?;
        write!(
            f,
            "  periodic ripple of the loop effort (orders 1–{PERIODIC_ORDERS}): {:.4} → {:.4} mN·m RMS ({:.0}× less)",
            1e3 * self.ripple_before_nm,
            1e3 * self.ripple_after_nm,
            self.ripple_reduction
        )?;
        for w in &self.warnings {
            write!(f, "\n  warning (feed-forward-on fit): {w}")?;
        }
        Ok(())
    }
}

/// The result of `stepdamp identify run` (its `--format json`): the plan, and with
/// `--refine` the feed-forward-off fit's report and the refinement.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunReport {
    /// The plan that was simulated.
    pub plan: crate::plan::Plan,
    /// The feed-forward-off fit of the simulated logs (with `--refine`).
    pub fit: Option<crate::fit::FitReport>,
    /// The refinement (with `--refine`).
    pub refinement: Option<RefinementReport>,
}
