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
//! result is the estimate of the last step.
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
}

/// Result of the refinement.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// Every step, the first being the starting estimate.
    pub steps: Vec<RefineStep>,
    /// The refined estimate.
    pub model: Model,
    /// The fit of the last feed-forward-on step (warnings, intervals, per-sample data).
    pub last_fit: Fit,
}

impl Refinement {
    /// Ripple of the loop effort before (no feed-forward) and after (last step), RMS N·m.
    pub fn ripple_before_after_nm(&self) -> (f64, f64) {
        let first = self.steps.first().map_or(0.0, |s| s.ripple_rms_nm);
        let last = self.steps.last().map_or(0.0, |s| s.ripple_rms_nm);
        (first, last)
    }
}

/// Why refinement failed.
#[derive(Debug, thiserror::Error)]
pub enum RefineError {
    /// The estimate does not make a valid profile.
    #[error("estimate: {0}")]
    Profile(#[from] ProfileError),
    /// The simulator refused.
    #[error("simulator: {0}")]
    Sim(#[from] SimError),
    /// A fit failed.
    #[error("fit: {0}")]
    Fit(#[from] FitError),
    /// Bad options.
    #[error("{0}")]
    Options(String),
}

/// The remaining ripple of logs recorded with feed-forward `current` on, fitted as `f`:
/// `RMS(δ)` in N·m (see the module documentation).
pub fn remaining_ripple_nm(current: &Model, ff_on: &Fit) -> f64 {
    Model::from_fit(ff_on).ripple_difference_rms_nm(current)
}

/// Refines `start` on the simulator: `motor` is the simulated plant, `plan` gives the runs
/// and the servo settings, `fit_options` the fit (orders, Km, J, …). `tick` is called once
/// per simulated run.
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
    }];
    let mut current = start.clone();
    let mut last_fit = None;
    // The feed-forward acts at the controller's (quantised) angle: no averaging correction.
    let fit_options = &FitOptions { correct_quantisation: false, ..fit_options.clone() };
    for it in 1..=o.max_iterations {
        let controller = current.apply_to(&plan.profile, None, "refinement estimate")?;
        let seed = crate::plan::run_seed(o.seed, 1000 + it as u64);
        let logs = simulate_plan(motor, &controller, Compensation::Patent, plan, o.current_noise_a, seed, tick)?;
        let f = fit(&logs, fit_options)?;
        let next = Model::from_fit(&f);
        let ripple = next.ripple_difference_rms_nm(&current);
        let previous = steps.last().map_or(f64::INFINITY, |s| s.ripple_rms_nm);
        steps.push(RefineStep {
            iteration: it,
            model: next.clone(),
            ripple_rms_nm: ripple,
            residual_rms_nm: f.residual_rms_nm,
        });
        current = next;
        last_fit = Some(f);
        if it > 1 && ripple > (1.0 - o.min_improvement) * previous {
            break;
        }
    }
    Ok(Refinement { steps, model: current, last_fit: last_fit.expect("at least one iteration") })
}
