//! Least-squares identification of detent harmonics and friction from servo-mode logs
//! (docs/design.md#identification).
//!
//! # Model
//!
//! With the rotor driven by a position servo, the torque the motor makes balances the
//! detent, the friction and the inertia at every instant:
//!
//! ```text
//! Km·i_q − J·dω/dt = Σ_k A_k sin(k·Nr·θ + φ_k) + Fs·sgn(ω) + D·ω + c
//!                  = Σ_k [a_k sin(k·Nr·θ) + b_k cos(k·Nr·θ)] + Fs·sgn(ω) + D·ω + c
//! ```
//!
//! with `a_k = A_k cos φ_k`, `b_k = A_k sin φ_k` (the profile's convention: the detent
//! torque on the rotor is `−Σ A_k sin(k·Nr·θ + φ_k)`, so the motor must supply `+Σ…`), and
//! `c` a constant torque (a load, or a current-sensor offset seen as torque), fitted only
//! when both directions of travel are logged. Every term is linear in the unknowns, so one
//! least-squares solve ([`crate::lsq`], the crate's one solver) gives all of them with their covariance; which of
//! `D` and `c` are fitted depends on the runs logged (see *Friction terms* below).
//!
//! # Choices
//!
//! * **`θ`** is the edge-timed angle of [`crate::stick`] when
//!   [`FitOptions::correct_quantisation`] is set (the default; logs without feed-forward):
//!   each change of the encoder count is placed at the count boundary in the middle of the
//!   sample period in which it happened, and the angle is interpolated between changes. It
//!   follows the true angle, whose function the detent torque is, without the staircase of
//!   the quantised `θ_fb`, so the harmonics need no correction for the encoder's averaging
//!   (the `sinc(k·π·Nr/cpr)` factor a staircase angle would call for); samples where the
//!   rotor is stuck are left out ([`crate::stick`]). Without the option (feed-forward-on
//!   logs, whose fixed point is the feed-forward in the controller's quantised angle) `θ` is
//!   the logged `θ_fb`, uncorrected.
//! * **`J·dω/dt` is kept.** At the slow speeds identification uses, the servo does *not*
//!   hold the speed: encoder-quantisation jitter and the detent make it ripple by tens of
//!   percent, and the share of the detent torque that goes into accelerating the rotor is
//!   `≈ (k·Nr·|ω| / ω_servo)²` (10 % at a third of the loop bandwidth). Dropping the term
//!   biased harmonic amplitudes by 2–12 % in simulation; keeping it, by ≈ 1 %. `dω/dt`
//!   comes from `θ_fb` smoothed with a zero-phase low-pass ([`crate::kinematics`]); `J` is
//!   identified (below), or held at [`FitOptions::inertia_kg_m2`] (a relative error `x` in
//!   `J` then moves the harmonics by about `x ·` [`RunSummary::inertial_share`]).
//!
//! # Inertia
//!
//! A user's profile carries a guessed `J` (the preset's, or the bare rotor's without the
//! load). Held at the preset's while the true one was ×0.5–×3 of it, the fit missed
//! harmonic amplitudes by up to 35 % and `Fs` by up to 18 % (50 random motors). So `J` is a
//! regressor ([`FitOptions::fit_inertia`], on by default): the model is linear in it.
//!
//! * **Instrument.** Regressing on the smoothed `dω/dt` itself gave `J` 0.14–2.9× the
//!   truth: the encoder's quantisation noise is in the regressor (errors in variables) and,
//!   through the servo, in the torque too (closed-loop correlation). The column is therefore
//!   each log's own *periodic part* of `dω/dt` (its least-squares fit on `sin, cos(k·θe)`
//!   of the fitted orders and a constant) — an instrumental variable: it carries the
//!   acceleration the detent causes, not the jitter. It is separable from the harmonics
//!   because the servo turns the detent into acceleration with a different gain and phase
//!   at each speed and in each direction (the phase flips with the direction), which is
//!   why the plan's two speeds in both directions matter. Variance inflation of the `J`
//!   column is ≈ 6 with the plan's runs.
//! * **Smoothing.** The effort is low-passed with the filter that gave `dω/dt`
//!   ([`FitOptions::smooth_effort`]), so `Km·i_q` and `J·dω/dt` see the same band, and the
//!   harmonic regressors are scaled by that filter's gain at their frequency (≥ 0.998).
//!   Feed-forward-on fits keep the raw effort (the feed-forward is a staircase in `θ_fb`)
//!   and hold `J` (the rotor then hardly accelerates): [`crate::refine`].
//! * **Measured** (50 random motors, `J` ×0.5–×3 of the base profile's, no detent in it):
//!   `J` within 1.2 % of the truth, harmonics within 0.29 %, phases 0.0035 rad, `Fs`
//!   0.79 % (worst of each over the 50; the crate's test
//!   `fifty_random_motors_are_identified_…`, which prints them, with 15 electrical periods
//!   per run; `patent-motor` with the full plan: 0.23 %, 0.0003 rad, `Fs` 0.03 %, `J`
//!   +0.6 %).
//!   A `J` that differs from the base profile's by more than
//!   [`FitOptions::max_inertia_disagreement`] is warned about, and one poorly determined
//!   (interval wider than that fraction) too. The identified `J` goes into the output
//!   profile's `inertia_kg_m2` ([`crate::model::Model::apply_to`]).
//! * **Friction columns use the run's mean speed** `ω̄` (the slope of the straight line
//!   through `θ_fb(t)` over the steady window): `Fs·sgn(ω̄)`, `D·ω̄`. The viscous torque
//!   of the speed ripple, `D·(ω − ω̄)`, is subtracted from the data with `D` from a first
//!   pass (the fallback) and then from the fit itself (two passes). Letting the
//!   instantaneous, smoothed `ω` carry the friction columns mixed the speed ripple into
//!   `D` (+40 % and more) and `Fs` (−10 to −45 %) in simulation.
//! * **Used samples**: the steady window of each log (from the first to the last sample at
//!   ≥ 80 % of the mean speed, away from the filter's start-up: the start from rest, the
//!   ramp and a final stop are dropped), minus samples where the rotor is (nearly) stopped,
//!   `ω·sgn(ω̄) < ` [`FitOptions::min_speed_fraction`]`·|ω̄|`: there static friction holds
//!   whatever torque is needed and the model does not apply.
//!
//! # Friction terms
//!
//! The friction columns `sgn(ω̄)`, `ω̄` and `1` are constant over each log, so they can only
//! be told apart by the distinct *levels* (direction, `|ω̄|`) the logs cover; speeds less
//! than [`SPEED_RATIO`] apart in one direction count as one level. Only the runs the fit
//! really uses count: a run whose rotor moves in less than
//! [`MIN_MOVING_PERIODS`](crate::conditions::MIN_MOVING_PERIODS) electrical period's worth of
//! samples is left out before `D` and `J` are decided ([`crate::conditions`], *Runs that
//! hardly move*). `Fs` is always fitted
//! (with one level it absorbs `c` and any error of the `D` held); the others only where the levels separate
//! them, and a term that is not fitted is held, with a warning naming it and the run to add:
//!
//! | levels logged | fitted | held |
//! |---|---|---|
//! | one direction, one speed | `Fs` | `D` at the fallback, `c = 0` (absorbed by `Fs`) |
//! | one direction, two speeds | `Fs`, `D` | `c = 0` (absorbed by `Fs`) |
//! | both directions, one speed (the same, or one per direction) | `Fs`, `c` | `D` at the fallback |
//! | both directions, two speeds in at least one of them | `Fs`, `D`, `c` | — |
//!
//! `D` needs two speeds *in the same direction*: forward at one speed and reverse at
//! another give two levels for three unknowns. There `D` is held at
//! [`FitOptions::viscous_fallback_nm_s_per_rad`] rather than `c` at 0: a constant torque
//! (load, current offset) is common and would bias both `Fs` and `D`, while a wrong `D` at
//! the slow speeds of identification moves `Fs` by only `ΔD·|ω̄|`. With these rules the
//! friction columns are always linearly independent.
//!
//! # Error bounds
//!
//! Confidence intervals (95 %, half-widths) come from the coefficient covariance of
//! [`crate::lsq`] (the larger of the classical and the block-robust estimate, blocks of one
//! electrical period), propagated to amplitude and phase by the delta method:
//! `σ_A² = gᵀΣg` with `g = (a, b)/A`, `σ_φ² = hᵀΣh` with `h = (−b, a)/A²`. They cover
//! measurement noise and loop jitter, **not bias**. Measured bias on the simulator with the
//! plan of [`crate::plan`] (4000 counts, `Nr` = 50, current noise 0.01 A), `J` identified:
//! amplitudes within 0.29 %, phases within 0.0035 rad, `Fs` within 0.79 % (worst over 50
//! random motors, see *Inertia*); refinement ([`crate::refine`]) leaves ≈ 0.15 %
//! (patent-motor: 0.22 % → 0.15 %, phase 0.0014 → 0.0008 rad). A wrong
//! `Km` scales the result; an order not fitted stays in the residual and does not leak into the others when
//! the logs cover whole electrical periods. Runs too slow for the encoder (count rate below
//! the servo bandwidth in rad/s) underestimate `Fs` by 10–40 %: see the warnings.
//!
//! # Cost
//!
//! `O(n·p²)` for `n` samples and `p` unknowns (QR), twice: ≈ 0.1 s for 200 000 samples and
//! orders 1, 2, 4 in a release build.
//!
//! # Code
//!
//! `prepare` makes each log ready (angle, kinematics, steady window), `design` builds
//! the regressors, `solve` solves them with [`crate::lsq`] and makes the [`Fit`], `warnings`
//! holds the warnings and their checks, `thresholds` the fixed numbers with their sources;
//! the decisions about the conditions (slow runs, `J`) live in [`crate::conditions`] and
//! [`crate::stick`].

mod design;
mod options;
mod prepare;
mod report;
mod result;
mod sanity;
mod solve;
pub(crate) mod thresholds;
mod warnings;

pub use options::{Effort, FitOptions};
pub use report::{FeedForwardCheck, FitReport};
pub use result::{Estimate, Fit, FitError, FitSamples, HarmonicEstimate, RunSummary, polar_with_ci, wrap_pi};
pub(crate) use thresholds::Z_95;
pub use warnings::Warning;

use crate::log::RunLog;
use prepare::{Prepared, prepare};
use solve::fit_prepared;

/// Default harmonic orders of the fit: [`stepdamp_profile::TYPICAL_DETENT_ORDERS`].
pub const DEFAULT_ORDERS: [u16; 3] = stepdamp_profile::TYPICAL_DETENT_ORDERS;

/// Two speeds in one direction separate `D` from `Fs` when the faster is at least this many
/// times the slower (see the module documentation, *Friction terms*).
pub const SPEED_RATIO: f64 = 1.3;

/// Fits the model to the logs.
///
/// Two passes: the first subtracts the viscous torque of the speed ripple,
/// `D·(ω − ω̄)`, with [`FitOptions::viscous_fallback_nm_s_per_rad`]; the second with the
/// `D` the first found (when it could be fitted).
pub fn fit(logs: &[RunLog], o: &FitOptions) -> Result<Fit, FitError> {
    o.check()?;
    if logs.is_empty() {
        return Err(FitError::NoLogs);
    }
    let kmax = *o.orders.iter().max().expect("checked non-empty");
    // Back-EMF runs (fast, with the phase signals) are for the flux linkage (crate::emf),
    // unless there is nothing else.
    let emf = |l: &&RunLog| l.phases.is_some() && crate::emf::is_emf_run(l, o.pole_pairs);
    let back_emf: Vec<String> = logs.iter().filter(emf).map(|l| l.source.clone()).collect();
    let left_out_emf = back_emf.len() < logs.len() && !back_emf.is_empty();
    let mut prepared = logs
        .iter()
        .filter(|l| !(left_out_emf && emf(l)))
        .map(|l| prepare(l, o, kmax))
        .collect::<Result<Vec<_>, _>>()?;
    // Hook (crate::conditions): slow runs short of friction are left out.
    let speeds: Vec<f64> = prepared.iter().map(|p| p.speed).collect();
    let held = FitOptions { fit_inertia: false, ..o.clone() };
    let reacts: Vec<bool> = prepared.iter().map(|p| p.reacts_to_counts).collect();
    let left_out = crate::conditions::slow_levels_to_leave_out(&speeds, &reacts, |runs| {
        let sub: Vec<&Prepared> = runs.iter().map(|&i| &prepared[i]).collect();
        fit_prepared(&sub, &held, o.viscous_fallback_nm_s_per_rad).ok().map(|f| f.coulomb_friction_nm.value)
    });
    let condition = left_out.map(|l| {
        let runs = l.runs.iter().map(|&i| prepared[i].log.source.clone()).collect();
        let mut i = 0;
        prepared.retain(|_| (!l.runs.contains(&i), i += 1).0);
        let viscous_held = o.viscous_fallback_nm_s_per_rad;
        let (fs_slow_nm, fs_fast_nm, slow_rad_s, fast_rad_s) = (l.fs_slow_nm, l.fs_fast_nm, l.slow_rad_s, l.fast_rad_s);
        Warning::Condition(crate::conditions::Condition::SlowRunsLeftOut {
            runs,
            fs_slow_nm,
            fs_fast_nm,
            slow_rad_s,
            fast_rad_s,
            viscous_held,
        })
    });
    // Hook (crate::conditions): runs that hardly move are no speed level.
    let motion = leave_out_still(&mut prepared);
    // Hook (crate::conditions): fit J or hold the base's, and say which.
    let prepared: Vec<&Prepared> = prepared.iter().collect();
    let speeds: Vec<f64> = prepared.iter().map(|p| p.speed).collect();
    let choice = crate::conditions::inertia_choice(o.fit_inertia, o.inertia, &speeds);
    let mut f = two_passes(&prepared, &FitOptions { fit_inertia: choice.is_ok(), ..o.clone() })?;
    sanity::refuse_unphysical(&f)?;
    let decision = match (choice, f.inertia_kg_m2) {
        (Ok(forced), Some(j)) if forced || j.ci95 <= crate::conditions::MAX_INERTIA_INTERVAL * j.value => {
            crate::conditions::Decision::InertiaFitted { value: j.value, ci95: j.ci95, forced }
        }
        (Ok(_), Some(j)) => {
            f = two_passes(&prepared, &held)?;
            sanity::refuse_unphysical(&f)?;
            let reason = if j.value > 0.0 {
                format!("its interval ±{:.0} % is wide (the fit gave {:.4e} kg·m²)", 100.0 * j.ci95 / j.value, j.value)
            } else {
                format!("the fit gave a J that is not positive ({:.4e} ± {:.1e} kg·m²)", j.value, j.ci95)
            };
            crate::conditions::Decision::InertiaHeld { base: o.inertia_kg_m2, reason }
        }
        (Err(reason), _) => crate::conditions::Decision::InertiaHeld { base: o.inertia_kg_m2, reason },
        (Ok(_), None) => {
            crate::conditions::Decision::InertiaHeld { base: o.inertia_kg_m2, reason: "not fitted".into() }
        }
    };
    f.warnings.splice(0..0, condition.into_iter().chain(motion));
    if left_out_emf {
        f.decisions.push(crate::conditions::Decision::BackEmfRunsLeftOut { runs: back_emf });
    }
    f.decisions.push(decision);
    Ok(f)
}

/// Leaves out the runs the rotor hardly moves in ([`crate::conditions::runs_without_motion`])
/// and returns the warning naming them, if any.
fn leave_out_still(prepared: &mut Vec<Prepared>) -> Option<Warning> {
    let moving: Vec<f64> = prepared.iter().map(|p| p.moving_periods).collect();
    let still = crate::conditions::runs_without_motion(&moving);
    if still.is_empty() {
        return None;
    }
    let runs = still.iter().map(|&i| prepared[i].log.source.clone()).collect();
    let moving_periods = still.iter().map(|&i| moving[i]).collect();
    let mut i = 0;
    prepared.retain(|_| (!still.contains(&i), i += 1).0);
    Some(Warning::Condition(crate::conditions::Condition::TooLittleMotion { runs, moving_periods }))
}

fn two_passes(prepared: &[&Prepared], o: &FitOptions) -> Result<Fit, FitError> {
    let first = fit_prepared(prepared, o, o.viscous_fallback_nm_s_per_rad)?;
    match first.viscous_nm_s_per_rad {
        Some(d) => fit_prepared(prepared, o, d.value.max(0.0)),
        None => Ok(first),
    }
}
