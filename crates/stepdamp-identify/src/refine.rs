//! Refinement by the patent's own criterion (§A, claim 1): with the identified
//! feed-forward switched on in servo mode, tune it until the periodic torque ripple the
//! loop still has to supply is gone.
//!
//! # The step
//!
//! With the feed-forward of the current estimate `M` on (servo mode, compensation
//! `Patent`: the detent series of `M` at `θ_fb` plus `Fs·sgn(ω_cmd)`), the loop's effort
//! beyond the feed-forward is `Km·i_q − J·dω/dt − FF_M(θ_fb)`. Its periodic part, fitted on
//! the same harmonics as [`crate::fit`], is the error of `M` as the loop sees it; the
//! corrected estimate is `M + δ`. Because the fit is linear, `M + δ` is exactly the fit of
//! the feed-forward-on logs themselves, so the step is [`crate::fit::fit`] on those logs,
//! and the **remaining ripple** it reports is `RMS(δ) = √(Σ|δ_k|²/2)` with `δ_k` the
//! complex difference of the harmonics. What changes from the first, feed-forward-off fit
//! is the data: with the detent cancelled the rotor runs smoothly, so the errors that scale
//! with the rotor's ripple (`J·dω/dt` from a quantised encoder, what the loop did not follow)
//! shrink with it, and the estimate moves to what the drive actually needs.
//!
//! Iterations stop when the remaining ripple falls by less than
//! [`RefineOptions::min_improvement`] (or after [`RefineOptions::max_iterations`]); the
//! result is the estimate of the last step. That estimate is then **checked**: the runs are
//! repeated once more with it fed forward, and the ripple left is reported
//! ([`Refinement::check`]). Besides `RMS(δ)` on the fitted orders, every step reports the
//! periodic ripple of the effort beyond the feed-forward over **all** orders 1–16
//! ([`RefineStep::periodic_rms_nm`]), so orders that were not fitted are not hidden.
//!
//! # On a real drive
//!
//! 1. Record the plan's runs with compensation off; `stepdamp identify --log … --motor
//!    base.toml --out id1.toml`.
//! 2. Load `id1.toml`'s detent and `Fs` into the drive's feed-forward (servo mode,
//!    compensation on) and record the same runs again.
//! 3. `stepdamp identify --log ff-… --motor id1.toml --ff-on --out id2.toml`: the fit of
//!    these logs is the corrected estimate, and `--ff-on` makes it print the remaining ripple
//!    (the difference between `id1.toml`'s feed-forward and what the loop needed).
//! 4. Repeat 2–3 with the new profile while the remaining ripple keeps falling.

mod report;
pub use report::{RefinementReport, ReportStep, RunReport, SummaryRow};

use crate::fit::{Fit, FitError, FitOptions, fit};
use crate::model::Model;
use crate::plan::{Plan, simulate_plan};
use stepdamp_sim::{Compensation, Profile, ProfileError, SimError};

/// Options of the refinement.
#[derive(Clone, Debug, PartialEq)]
pub struct RefineOptions {
    /// Most feed-forward-on iterations.
    pub max_iterations: usize,
    /// Stop when the remaining ripple falls by less than this fraction.
    pub min_improvement: f64,
    /// Current-sensor noise of the simulation, A.
    pub current_noise_a: f64,
    /// Base seed (each iteration and run derive their own).
    pub seed: u64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions { max_iterations: 3, min_improvement: 0.2, current_noise_a: 0.01, seed: 1 }
    }
}

/// One step of the refinement.
#[derive(Clone, Debug, PartialEq)]
pub struct RefineStep {
    /// 0: the feed-forward-off estimate; 1…: feed-forward-on corrections.
    pub iteration: usize,
    /// The estimate after this step.
    pub model: Model,
    /// Periodic ripple of the loop effort beyond the feed-forward, RMS N·m: for step 0
    /// (no feed-forward) the whole fitted detent ripple; then `RMS(δ)`.
    pub ripple_rms_nm: f64,
    /// Residual RMS of the step's fit, N·m.
    pub residual_rms_nm: f64,
    /// Periodic ripple (orders 1 to [`PERIODIC_ORDERS`] of the electrical angle, RMS N·m) of
    /// the effort beyond the feed-forward that ran while this step's logs were recorded
    /// (none for step 0, the previous step's estimate after).
    pub periodic_rms_nm: f64,
}

/// Highest order counted in [`RefineStep::periodic_rms_nm`].
pub const PERIODIC_ORDERS: usize = 16;

/// The check run: the final estimate fed forward.
#[derive(Clone, Debug)]
pub struct RefineCheck {
    /// `RMS(δ)` on the fitted orders with the final estimate on, N·m.
    pub ripple_rms_nm: f64,
    /// Periodic ripple of the effort beyond the final estimate, orders 1–16, RMS N·m.
    pub periodic_rms_nm: f64,
    /// The fit of the check runs (warnings, intervals, per-sample data).
    pub fit: Fit,
}

/// Result of the refinement.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Every step, the first being the starting estimate.
    pub steps: Vec<RefineStep>,
    /// The refined estimate.
    pub model: Model,
    /// The check run with [`Refinement::model`] fed forward.
    pub check: RefineCheck,
}

impl Refinement {
    /// Periodic ripple of the loop effort (all orders 1–16, RMS N·m) before (no
    /// feed-forward) and after (the refined estimate fed forward, measured by the check run).
    pub fn ripple_before_after_nm(&self) -> (f64, f64) {
        let first = self.steps.first().map_or(f64::NAN, |s| s.periodic_rms_nm);
        (first, self.check.periodic_rms_nm)
    }
}

pub use crate::model::series_nm;

/// Periodic ripple (orders 1–[`PERIODIC_ORDERS`], RMS N·m) of a fit's needed torque beyond
/// the feed-forward `ff` (if any) that ran while its logs were recorded.
pub fn periodic_ripple_nm(f: &Fit, ff: Option<&Model>) -> f64 {
    let s = &f.samples;
    let beyond: Vec<f64> = match ff {
        Some(m) => s.theta_e_rad.iter().zip(&s.ripple_nm).map(|(&th, &y)| y - series_nm(m, th)).collect(),
        None => s.ripple_nm.clone(),
    };
    let spec = crate::spectrum::order_spectrum(&s.theta_e_rad, &beyond, PERIODIC_ORDERS, 256);
    (spec.iter().skip(1).map(|a| a * a / 2.0).sum::<f64>()).sqrt()
}

/// Why refinement failed. The inner error is part of the message (not a `source`), so an
/// error chain prints it once.
#[derive(Debug, thiserror::Error)]
pub enum RefineError {
    /// The estimate does not make a valid profile.
    #[error("estimate: {0}")]
    Profile(ProfileError),
    /// The simulator refused.
    #[error("simulator: {0}")]
    Sim(SimError),
    /// A fit failed.
    #[error("fit: {0}")]
    Fit(FitError),
    /// Bad options.
    #[error("{0}")]
    Options(String),
}

impl From<ProfileError> for RefineError {
    fn from(e: ProfileError) -> Self {
        RefineError::Profile(e)
    }
}

impl From<SimError> for RefineError {
    fn from(e: SimError) -> Self {
        RefineError::Sim(e)
    }
}

impl From<FitError> for RefineError {
    fn from(e: FitError) -> Self {
        RefineError::Fit(e)
    }
}

/// Refines `start` on the simulator: `motor` is the simulated plant, `plan` gives the runs
/// and the servo settings, `fit_options` the fit (orders, Km, J, …). `tick` is called once
/// per simulated run: `plan.runs.len() × (iterations + 1)` times at most (the last round
/// is the check).
pub fn refine(
    motor: &Profile,
    plan: &Plan,
    start: &Model,
    start_fit: Option<&Fit>,
    fit_options: &FitOptions,
    o: &RefineOptions,
    tick: &(dyn Fn() + Sync),
) -> Result<Refinement, RefineError> {
    if o.max_iterations == 0 || o.max_iterations > 20 {
        return Err(RefineError::Options(format!("{} iterations: must be in 1..=20", o.max_iterations)));
    }
    if !(o.min_improvement.is_finite() && (0.0..1.0).contains(&o.min_improvement)) {
        return Err(RefineError::Options(format!("min improvement {}: must be in [0, 1)", o.min_improvement)));
    }
    let mut steps = vec![RefineStep {
        iteration: 0,
        model: start.clone(),
        ripple_rms_nm: start.ripple_rms_nm(),
        residual_rms_nm: start_fit.map_or(f64::NAN, |f| f.residual_rms_nm),
        periodic_rms_nm: start_fit.map_or(f64::NAN, |f| periodic_ripple_nm(f, None)),
    }];
    let mut current = start.clone();
    // The feed-forward acts at the controller's (quantised) angle: no averaging correction.
    // `J` is held at the starting estimate's: with the detent cancelled the rotor hardly
    // accelerates, and the feed-forward-on logs carry little information on it.
    let inertia = start.inertia_kg_m2.or(start_fit.map(|f| f.inertia_used)).unwrap_or(fit_options.inertia_kg_m2);
    let fit_options = &FitOptions {
        correct_quantisation: false,
        smooth_effort: false,
        fit_inertia: false,
        inertia_kg_m2: inertia,
        ..fit_options.clone()
    };
    // Records the plan's runs with `ff` fed forward (the plan's servo gains kept) and fits
    // them; the estimates carry the starting `J`.
    let run_with = |ff: &Model, round: u64| -> Result<Fit, RefineError> {
        let ff = Model { inertia_kg_m2: None, ..ff.clone() };
        let controller = ff.apply_to(&plan.profile, None, "refinement estimate")?;
        let seed = crate::plan::run_seed(o.seed, 1000 + round);
        let logs = simulate_plan(motor, &controller, Compensation::Patent, plan, o.current_noise_a, seed, tick)?;
        Ok(fit(&logs, fit_options)?)
    };
    for it in 1..=o.max_iterations {
        let f = run_with(&current, it as u64)?;
        let next = Model { inertia_kg_m2: current.inertia_kg_m2, ..Model::from_fit(&f) };
        let ripple = next.ripple_difference_rms_nm(&current);
        let previous = steps.last().map_or(f64::INFINITY, |s| s.ripple_rms_nm);
        steps.push(RefineStep {
            iteration: it,
            model: next.clone(),
            ripple_rms_nm: ripple,
            residual_rms_nm: f.residual_rms_nm,
            periodic_rms_nm: periodic_ripple_nm(&f, Some(&current)),
        });
        current = next;
        if it > 1 && ripple > (1.0 - o.min_improvement) * previous {
            break;
        }
    }
    let f = run_with(&current, 999)?;
    let check = RefineCheck {
        ripple_rms_nm: Model::from_fit(&f).ripple_difference_rms_nm(&current),
        periodic_rms_nm: periodic_ripple_nm(&f, Some(&current)),
        fit: f,
    };
    Ok(Refinement { steps, model: current, check })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{PlanOptions, plan};

    #[test]
    fn ripple_of_orders_left_out_of_the_fit_is_still_reported_after_refinement() {
        // Fit order 4 only: refinement cancels it, but orders 1 and 2 (8 and 12 mN·m,
        // ≈ 10 mN·m RMS together) stay in the loop effort and must show in "after".
        let m = Profile::preset("patent-motor").unwrap();
        let o = PlanOptions { orders: vec![4], electrical_periods: 10.0, min_steady_s: 0.5, ..PlanOptions::default() };
        let p = plan(&m, &o).unwrap();
        let logs = simulate_plan(&m, &p.profile, Compensation::Off, &p, o.current_noise_a, 5, &|| {}).unwrap();
        let fo = FitOptions::for_profile(&p.profile, &[4]);
        let f0 = fit(&logs, &fo).unwrap();
        let ro = RefineOptions { max_iterations: 1, ..RefineOptions::default() };
        let r = refine(&m, &p, &Model::from_fit(&f0), Some(&f0), &fo, &ro, &|| {}).unwrap();
        let (before, after) = r.ripple_before_after_nm();
        let untouched = (0.008f64.powi(2) / 2.0 + 0.012f64.powi(2) / 2.0).sqrt();
        assert!(r.check.ripple_rms_nm < 0.001, "order 4 left: {}", r.check.ripple_rms_nm);
        assert!((after - untouched).abs() < 0.1 * untouched, "after {after}, orders 1 and 2 carry {untouched}");
        assert!(before > after, "{before} → {after}");
    }
}
