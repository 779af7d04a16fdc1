//! Least-squares identification of detent harmonics and friction from servo-mode logs
//! (design.md §5).
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
//! least-squares solve ([`crate::lsq`]) gives all of them with their covariance; which of
//! `D` and `c` are fitted depends on the runs logged (see *Friction terms* below).
//!
//! # Choices
//!
//! * **`θ`** is the encoder angle `θ_fb`. Quantisation to `cpr` counts/rev smears each
//!   regressor: averaged over a count, `E[sin(kθe)] = sinc(k·π·Nr/cpr)·sin(kθe_fb)`, so the
//!   fitted `a_k, b_k` are divided by that factor (0.4 % for k = 4, Nr = 50, 4000 counts)
//!   when [`FitOptions::correct_quantisation`] is set and the resolution is known.
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
//!   `J` within +0.6 … +4.8 % (a small positive bias, ≈ +2 % typical; the 95 % intervals,
//!   1–5 %, do not always cover it), harmonics within 0.83 %, phases 0.007 rad, `Fs` 2.3 %.
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
//! than [`SPEED_RATIO`] apart in one direction count as one level. `Fs` is always fitted
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
//! amplitudes within 0.83 %, phases within 0.007 rad, `Fs` within 2.3 % (worst over 50
//! random motors, see *Inertia*); refinement ([`crate::refine`]) leaves ≈ 0.1 %. A wrong
//! `Km` scales the result; an order not fitted stays in the residual and does not leak into the others when
//! the logs cover whole electrical periods. Runs too slow for the encoder (count rate below
//! the servo bandwidth in rad/s) underestimate `Fs` by 10–40 %: see the warnings.
//!
//! # Cost
//!
//! `O(n·p²)` for `n` samples and `p` unknowns (QR), twice: ≈ 0.1 s for 200 000 samples and
//! orders 1, 2, 4 in a release build.

use crate::kinematics::{self, Kinematics};
use crate::log::RunLog;
use crate::lsq::{self, Design, LsqError};
use std::f64::consts::{PI, TAU};
use stepdamp_profile::Profile;

/// Default harmonic orders of the fit: [`stepdamp_profile::TYPICAL_DETENT_ORDERS`].
pub const DEFAULT_ORDERS: [u16; 3] = stepdamp_profile::TYPICAL_DETENT_ORDERS;

/// Two speeds in one direction separate `D` from `Fs` when the faster is at least this many
/// times the slower (see the module documentation, *Friction terms*).
pub const SPEED_RATIO: f64 = 1.3;

/// The fit's angle is the edge-timed one of [`crate::stick`] whenever
/// [`FitOptions::correct_quantisation`] is set (the torque follows the true angle).
const EDGE_TIMED_ANGLE: bool = true;

/// Fewest samples of steady running a log must leave for the fit (after the speed filter's
/// start-up at each end is dropped).
const MIN_STEADY_SAMPLES: usize = 17;

/// Which signal is the loop's effort.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Effort {
    /// The measured q current `i_q_a` (the torque the motor actually made).
    #[default]
    MeasuredIq,
    /// The loop's q current command `iq_cmd_a` (what the loop asked for).
    CommandIq,
}

/// Options of the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Harmonic orders `k` of the electrical angle to fit (distinct, ≥ 1).
    pub orders: Vec<u16>,
    /// Rotor pole pairs `Nr`.
    pub pole_pairs: u16,
    /// Torque constant `Km` in N·m/A.
    pub km_nm_per_a: f64,
    /// Rotor + load inertia `J` in kg·m² for the `J·dω/dt` term: the value held when
    /// [`FitOptions::fit_inertia`] is off (0 = ignore inertia), and the reference the fitted
    /// `J` is compared with when it is on.
    pub inertia_kg_m2: f64,
    /// Fit `J` as one more regressor on `dω/dt` (see the module documentation, *Inertia*)
    /// instead of holding [`FitOptions::inertia_kg_m2`].
    pub fit_inertia: bool,
    /// With [`FitOptions::fit_inertia`]: warn when the fitted `J` differs from
    /// [`FitOptions::inertia_kg_m2`] by more than this fraction.
    pub max_inertia_disagreement: f64,
    /// Encoder counts per revolution (for the quantisation correction and the smoothing
    /// corner); `None` when unknown.
    pub counts_per_rev: Option<u32>,
    /// Servo position-loop bandwidth in Hz (for the "too fast" warning); `None` when unknown.
    pub servo_bandwidth_hz: Option<f64>,
    /// `D` in N·m·s/rad used when the logs cannot separate it from `Fs` (one speed).
    pub viscous_fallback_nm_s_per_rad: f64,
    /// Effort signal.
    pub effort: Effort,
    /// Samples with `|ω| <` this fraction of the log's mean speed are left out (stiction).
    pub min_speed_fraction: f64,
    /// Fewest electrical periods in each direction before a warning.
    pub recommended_periods: f64,
    /// Divide the harmonics by the encoder's averaging factor `sinc(k·π·Nr/cpr)` (see the
    /// module documentation). Right for logs without feed-forward (the torque follows the
    /// true angle); off for feed-forward-on logs, whose fixed point is the feed-forward in
    /// the controller's own (quantised) angle.
    pub correct_quantisation: bool,
    /// Low-pass the effort with the filter that gives `dω/dt` (see the module
    /// documentation, *Inertia*). Right for logs without feed-forward; off for
    /// feed-forward-on logs, whose effort carries the feed-forward as a staircase in the
    /// encoder angle that must stay aligned with the regressors.
    pub smooth_effort: bool,
    /// Warn when more than this fraction of the encoder steps go against the direction of
    /// travel (the servo's quantisation jitter reverses the rotor, and friction is then
    /// underestimated).
    pub max_back_step_fraction: f64,
    /// Warn when `J·dω/dt` is more than this share of the fitted ripple.
    pub max_inertial_share: f64,
    /// Warn when a term's variance inflation factor exceeds this.
    pub max_inflation: f64,
    /// Stuck-sample detection ([`crate::stick`]).
    pub stick: crate::stick::StickOptions,
    /// How `J` is obtained when [`FitOptions::fit_inertia`] allows fitting it
    /// ([`crate::conditions`]).
    pub inertia: crate::conditions::InertiaMode,
}

impl FitOptions {
    /// Options for a motor profile (its `Km`, `Nr`, `J`, encoder, servo bandwidth and `D` as
    /// the fallback) and the given orders.
    pub fn for_profile(p: &Profile, orders: &[u16]) -> Self {
        FitOptions {
            orders: orders.to_vec(),
            pole_pairs: p.motor.pole_pairs,
            km_nm_per_a: p.motor.km_nm_per_a,
            inertia_kg_m2: p.motor.inertia_kg_m2,
            fit_inertia: true,
            max_inertia_disagreement: 0.2,
            counts_per_rev: Some(p.encoder.counts_per_rev),
            servo_bandwidth_hz: Some(p.servo.bandwidth_hz),
            viscous_fallback_nm_s_per_rad: p.motor.viscous_nm_s_per_rad,
            effort: Effort::MeasuredIq,
            min_speed_fraction: 0.1,
            recommended_periods: 10.0,
            correct_quantisation: true,
            smooth_effort: true,
            max_back_step_fraction: 0.02,
            max_inertial_share: 0.75,
            max_inflation: 50.0,
            stick: crate::stick::StickOptions::default(),
            inertia: crate::conditions::InertiaMode::Auto,
        }
    }
}

/// A value with its 95 % confidence half-width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Half-width of the 95 % confidence interval (same unit).
    pub ci95: f64,
}

/// One identified detent harmonic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarmonicEstimate {
    /// Order `k`.
    pub order: u16,
    /// Amplitude `A_k` in N·m with its 95 % half-width.
    pub amplitude_nm: Estimate,
    /// Phase `φ_k` in rad, in `(−π, π]`, profile convention, with its 95 % half-width.
    pub phase_rad: Estimate,
    /// `a_k = A_k cos φ_k` in N·m (coefficient of `sin kθe`).
    pub a_nm: f64,
    /// `b_k = A_k sin φ_k` in N·m (coefficient of `cos kθe`).
    pub b_nm: f64,
}

/// What a log contributed.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSummary {
    /// Source name.
    pub source: String,
    /// Mean speed in rad/s (slope of the line through `θ_fb(t)`).
    pub mean_speed_rad_s: f64,
    /// Duration of the steady window used, s.
    pub duration_s: f64,
    /// Electrical periods in the steady window.
    pub electrical_periods: f64,
    /// Samples used in the fit.
    pub samples_used: usize,
    /// Samples in the log.
    pub samples: usize,
    /// Frequency of the highest fitted harmonic at the mean speed, Hz.
    pub highest_harmonic_hz: f64,
    /// RMS of `J·dω/dt` over RMS of the detent ripple fitted (0–1+): how much the loop
    /// failed to hold the speed. A relative error `x` in `J` moves the harmonics by about
    /// `x·share`.
    pub inertial_share: f64,
    /// Fraction of the encoder steps against the direction of travel.
    pub back_step_fraction: f64,
}

/// Why the data cannot fully separate the model's terms (the fit still ran).
#[derive(Clone, Debug, PartialEq)]
pub enum Warning {
    /// Few electrical periods in a direction.
    FewPeriods {
        /// `forward` or `reverse`.
        direction: &'static str,
        /// Periods logged.
        periods: f64,
        /// Periods recommended.
        recommended: f64,
    },
    /// Only one direction of travel: `Fs` (and `D`) absorb any constant torque.
    OneDirection {
        /// The direction logged.
        direction: &'static str,
    },
    /// One speed only: `D` is not separable from `Fs`.
    SingleSpeed {
        /// The speed in rad/s.
        speed_rad_s: f64,
        /// The `D` used instead, N·m·s/rad.
        viscous_used: f64,
    },
    /// Both directions, but one speed in each (and different speeds): two levels for `Fs`,
    /// `D` and `c`, so `D` is held and `Fs` and `c` are fitted.
    OneSpeedPerDirection {
        /// Mean `|ω̄|` of the forward logs, rad/s.
        forward_rad_s: f64,
        /// Mean `|ω̄|` of the reverse logs, rad/s.
        reverse_rad_s: f64,
        /// The `D` used instead, N·m·s/rad.
        viscous_used: f64,
        /// A run that would separate `D`: its direction (`forward` or `reverse`) and speed
        /// in rad/s.
        add_run: (&'static str, f64),
    },
    /// The fitted `Fs` is negative (clamped to 0 in the profile) or not significantly above
    /// zero.
    CoulombNotPositive {
        /// Fitted `Fs`, N·m.
        value_nm: f64,
        /// Its 95 % half-width, N·m.
        ci95_nm: f64,
        /// The only direction logged, when `c` could not be fitted.
        one_direction: Option<&'static str>,
        /// The `D` held (not fitted), N·m·s/rad.
        viscous_held: Option<f64>,
    },
    /// The fitted `D` is negative (clamped to 0 in the profile).
    ViscousNegative {
        /// Fitted `D`, N·m·s/rad.
        value: f64,
        /// Its 95 % half-width, N·m·s/rad.
        ci95: f64,
    },
    /// A harmonic is too fast for the servo to follow.
    TooFast {
        /// Log.
        source: String,
        /// Harmonic order.
        order: u16,
        /// Its frequency at the log's speed, Hz.
        harmonic_hz: f64,
        /// Servo bandwidth, Hz.
        bandwidth_hz: f64,
    },
    /// Inertia carries a large share of the ripple (the loop did not hold the speed).
    InertialShare {
        /// Log.
        source: String,
        /// Share (see [`RunSummary::inertial_share`]).
        share: f64,
    },
    /// The encoder stepped backwards: servo jitter reverses the rotor faster than the
    /// smoothed speed shows, so friction is underestimated.
    Reversing {
        /// Log.
        source: String,
        /// Fraction of encoder steps that went backwards.
        fraction: f64,
    },
    /// The encoder counts slower than the servo reacts: quantisation jitter makes the rotor
    /// stop and start within a count, and friction comes out low.
    SlowForEncoder {
        /// Log.
        source: String,
        /// Encoder counts per second at the log's speed.
        count_rate_hz: f64,
        /// Counts per second recommended: the servo bandwidth in rad/s.
        needed_hz: f64,
    },
    /// Many samples left out because the rotor was (nearly) stopped.
    Stalled {
        /// Log.
        source: String,
        /// Fraction left out.
        fraction: f64,
    },
    /// A term is strongly correlated with others.
    Confounded {
        /// The term.
        term: String,
        /// Its variance inflation factor.
        inflation: f64,
    },
    /// The fitted `J` differs from the base profile's by more than
    /// [`FitOptions::max_inertia_disagreement`].
    InertiaDisagrees {
        /// Fitted `J`, kg·m².
        value: f64,
        /// Its 95 % half-width, kg·m².
        ci95: f64,
        /// The base profile's `J`, kg·m².
        base: f64,
    },
    /// The fitted `J` is not positive or its interval is wide: the logs hold too little
    /// acceleration that is not periodic with the detent.
    InertiaUncertain {
        /// Fitted `J`, kg·m².
        value: f64,
        /// Its 95 % half-width, kg·m².
        ci95: f64,
    },
    /// A harmonic smaller than its own uncertainty.
    NotSignificant {
        /// Order.
        order: u16,
    },
    /// A condition of the logs ([`crate::conditions`]).
    Condition(crate::conditions::Condition),
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::FewPeriods { direction, periods, recommended } => write!(
                f,
                "only {periods:.1} electrical periods logged {direction} (≥ {recommended:.0} recommended): harmonics are poorly averaged"
            ),
            Warning::OneDirection { direction } => write!(
                f,
                "only {direction} travel logged: Fs is confounded with any constant torque (load, current offset) and reported as the mean friction of that direction"
            ),
            Warning::SingleSpeed { speed_rad_s, viscous_used } => write!(
                f,
                "one speed only (|ω| ≈ {speed_rad_s:.3} rad/s): D cannot be separated from Fs; D held at {viscous_used:.3e} N·m·s/rad (log a second speed at least 1.3× apart)"
            ),
            Warning::OneSpeedPerDirection { forward_rad_s, reverse_rad_s, viscous_used, add_run: (dir, speed) } => {
                write!(
                    f,
                    "forward at {forward_rad_s:.3} rad/s and reverse at {reverse_rad_s:.3} rad/s only: with one speed per direction D·ω cannot be separated from Fs·sgn(ω) and the constant torque; D held at {viscous_used:.3e} N·m·s/rad, Fs and the constant torque fitted (log a second speed in one direction, e.g. {dir} at {speed:.3} rad/s)"
                )
            }
            Warning::CoulombNotPositive { value_nm, ci95_nm, one_direction, viscous_held } => {
                let (v, ci) = (1e3 * value_nm, 1e3 * ci95_nm);
                if *value_nm < 0.0 {
                    write!(
                        f,
                        "Fs fitted negative ({v:.3} ± {ci:.3} mN·m) and clamped to 0 in the profile: friction cannot drive the rotor"
                    )?;
                } else {
                    write!(f, "Fs = {v:.3} ± {ci:.3} mN·m is not significantly above 0")?;
                }
                match one_direction {
                    Some(dir) => write!(
                        f,
                        "; likely a constant torque (a load, or a current-sensor offset) counted as friction because only {dir} travel is logged (log the other direction too), or too little data"
                    )?,
                    None => write!(f, "; likely too little data or too much noise (log longer runs)")?,
                }
                match viscous_held {
                    Some(d) => write!(f, ", or the D held ({d:.3e} N·m·s/rad) is too large"),
                    None => Ok(()),
                }
            }
            Warning::ViscousNegative { value, ci95 } => write!(
                f,
                "D fitted negative ({value:.3e} ± {ci95:.1e} N·m·s/rad) and clamped to 0 in the profile: likely too little data, or speeds too close together to separate D from Fs"
            ),
            Warning::TooFast { source, order, harmonic_hz, bandwidth_hz } => write!(
                f,
                "{source}: harmonic {order} at {harmonic_hz:.1} Hz is not well inside the servo bandwidth {bandwidth_hz:.0} Hz: the loop does not follow it and the result leans on J·dω/dt from the encoder (run slower)"
            ),
            Warning::InertialShare { source, share } => write!(
                f,
                "{source}: J·dω/dt is {:.0} % of the detent ripple (the loop did not hold the speed): a 10 % error in J moves the harmonics by about {:.0} %",
                100.0 * share,
                10.0 * share
            ),
            Warning::Reversing { source, fraction } => write!(
                f,
                "{source}: {:.1} % of the encoder steps go backwards: the servo's jitter reverses the rotor, so Fs comes out low (run faster: count rate ≥ servo bandwidth in rad/s, or soften the servo)",
                100.0 * fraction
            ),
            Warning::SlowForEncoder { source, count_rate_hz, needed_hz } => write!(
                f,
                "{source}: the encoder counts {count_rate_hz:.0} times/s, fewer than the servo bandwidth in rad/s ({needed_hz:.0}): quantisation jitter stalls the rotor within a count and Fs comes out low (run faster)"
            ),
            Warning::Stalled { source, fraction } => write!(
                f,
                "{source}: rotor nearly stopped in {:.0} % of the samples (left out: static friction)",
                100.0 * fraction
            ),
            Warning::Confounded { term, inflation } => write!(
                f,
                "{term} is hard to separate from the other terms (variance inflation {inflation:.0}); its interval is wide"
            ),
            Warning::InertiaDisagrees { value, ci95, base } => write!(
                f,
                "J identified {value:.3e} ± {ci95:.1e} kg·m² differs from the base profile's {base:.3e} kg·m² by {:+.0} % (a load coupled to the rotor, or a wrong profile): the identified J is written to the profile; plan the servo again with it",
                100.0 * (value / base - 1.0)
            ),
            Warning::InertiaUncertain { value, ci95 } => write!(
                f,
                "J identified {value:.3e} ± {ci95:.1e} kg·m² is poorly determined (the rotor hardly accelerated apart from the detent ripple): the harmonics lean on it; log runs at two speeds in both directions"
            ),
            Warning::NotSignificant { order } => {
                write!(f, "harmonic {order} is smaller than its own 95 % interval: not detected")
            }
            Warning::Condition(c) => c.fmt(f),
        }
    }
}

/// Result of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// Harmonics in the order asked for.
    pub harmonics: Vec<HarmonicEstimate>,
    /// Coulomb friction `Fs` in N·m.
    pub coulomb_friction_nm: Estimate,
    /// Viscous friction `D` in N·m·s/rad; `None` when not separable (the fallback was used).
    pub viscous_nm_s_per_rad: Option<Estimate>,
    /// `D` used in the model (fitted or the fallback), N·m·s/rad.
    pub viscous_used: f64,
    /// Constant torque `c` in N·m (both directions logged only).
    pub offset_nm: Option<Estimate>,
    /// Rotor + load inertia `J` in kg·m² when fitted ([`FitOptions::fit_inertia`]).
    pub inertia_kg_m2: Option<Estimate>,
    /// `J` used in the model (fitted, or [`FitOptions::inertia_kg_m2`] held), kg·m².
    pub inertia_used: f64,
    /// RMS of the fit residual in N·m.
    pub residual_rms_nm: f64,
    /// RMS of the fitted detent ripple `Σ A sin(…)` over the samples, N·m.
    pub ripple_rms_nm: f64,
    /// Samples used.
    pub samples_used: usize,
    /// Condition number of the scaled regressors.
    pub condition: f64,
    /// Per-log summaries.
    pub runs: Vec<RunSummary>,
    /// Warnings.
    pub warnings: Vec<Warning>,
    /// Which `J` was used and why ([`crate::conditions`]).
    pub decisions: Vec<crate::conditions::Decision>,
    /// The samples used, for reports: electrical angle `Nr·θ_fb` (rad, wrapped to
    /// `[0, 2π)`), the torque the model explains (`Km·i − J·α` minus friction and `c`,
    /// N·m), and the residual (N·m).
    pub samples: FitSamples,
}

/// Per-sample data of a fit (for plots and spectra).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FitSamples {
    /// Electrical angle in rad, `[0, 2π)`.
    pub theta_e_rad: Vec<f64>,
    /// Periodic part of the needed torque (needed torque minus friction and offset), N·m.
    pub ripple_nm: Vec<f64>,
    /// Residual of the fit, N·m.
    pub residual_nm: Vec<f64>,
}

/// Why a fit could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitError {
    /// No logs given.
    #[error("no logs to fit")]
    NoLogs,
    /// Bad options.
    #[error("{0}")]
    Options(String),
    /// A log too short for the fit (whether or not the rotor moves).
    #[error(
        "{log}: too short: {samples} samples ({duration_s:.3} s, mean speed {speed:.3e} rad/s); at least {needed} are needed (more than 16 at steady speed, after the speed filter's start-up at each end): log a longer constant-speed run"
    )]
    TooShort {
        /// Log.
        log: String,
        /// Samples in the log.
        samples: usize,
        /// Its duration, s.
        duration_s: f64,
        /// Its mean speed, rad/s.
        speed: f64,
        /// Samples needed at this speed and sample rate.
        needed: usize,
    },
    /// A log in which the rotor (almost) does not move: at most one electrical period.
    #[error(
        "{log}: the rotor does not move: {periods:.2} electrical periods over the log (mean speed {speed:.3e} rad/s; more than one needed, and many for a good fit): identification needs constant-speed runs"
    )]
    NoMotion {
        /// Log.
        log: String,
        /// Its mean speed, rad/s.
        speed: f64,
        /// Electrical periods covered at that speed over the log.
        periods: f64,
    },
    /// A log long enough and moving, but not at a steady speed.
    #[error(
        "{log}: the speed is not steady: only {steady} samples lie between the first and the last sample running at ≥ 80 % of the mean speed {speed:.3e} rad/s (more than 16 needed): identification needs constant-speed runs"
    )]
    Unsteady {
        /// Log.
        log: String,
        /// Its mean speed, rad/s.
        speed: f64,
        /// Samples in the steady window found.
        steady: usize,
    },
    /// A value of the data or of the result is infinite or not a number: the data are out of
    /// range (too large to square in `f64`) or not numbers.
    #[error(
        "{what} is not finite (logs: {logs}; {detail}): values in the data are out of range (e.g. a current of 1e200 A) or not numbers; check the units and the columns"
    )]
    NonFinite {
        /// What is not finite.
        what: String,
        /// The logs fitted (their source names).
        logs: String,
        /// Where the data are largest (or not a number).
        detail: String,
    },
    /// Too few usable samples, or the terms cannot be separated at all. The cause is part
    /// of the message, not a `source`, so an error chain prints it once.
    #[error("least squares failed: {0}")]
    Lsq(LsqError),
}

impl From<LsqError> for FitError {
    fn from(e: LsqError) -> Self {
        FitError::Lsq(e)
    }
}

/// Wraps an angle to `(−π, π]`.
pub fn wrap_pi(x: f64) -> f64 {
    let y = x.rem_euclid(TAU);
    if y > PI { y - TAU } else { y }
}

/// `sin(x)/x`.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-9 { 1.0 } else { x.sin() / x }
}

impl FitOptions {
    fn check(&self) -> Result<(), FitError> {
        let bad = |m: String| Err(FitError::Options(m));
        if self.orders.is_empty() {
            return bad("no harmonic orders to fit".into());
        }
        for (i, &k) in self.orders.iter().enumerate() {
            if k == 0 || usize::from(k) > stepdamp_core::MAX_HARMONIC_ORDER {
                return bad(format!("harmonic order {k}: must be in 1..={}", stepdamp_core::MAX_HARMONIC_ORDER));
            }
            if self.orders[..i].contains(&k) {
                return bad(format!("harmonic order {k} is listed twice"));
            }
        }
        if self.pole_pairs == 0 {
            return bad("pole pairs must be ≥ 1".into());
        }
        if !(self.km_nm_per_a.is_finite() && self.km_nm_per_a > 0.0) {
            return bad(format!("Km = {}: must be > 0", self.km_nm_per_a));
        }
        if !(self.inertia_kg_m2.is_finite() && self.inertia_kg_m2 >= 0.0) {
            return bad(format!("J = {}: must be ≥ 0", self.inertia_kg_m2));
        }
        if !(self.min_speed_fraction.is_finite() && (0.0..1.0).contains(&self.min_speed_fraction)) {
            return bad(format!("min_speed_fraction = {}: must be in [0, 1)", self.min_speed_fraction));
        }
        Ok(())
    }
}

/// A log with its kinematics and the window of it that is used.
#[derive(Clone)]
struct Prepared<'a> {
    log: &'a RunLog,
    /// The angle the fit uses, rad: edge-timed or the logged `θ_fb` ([`crate::stick`]).
    theta: Vec<f64>,
    /// Samples where the rotor moves (not stuck, not within the margin of a stick).
    keep: Vec<bool>,
    /// Whether the drive reacts to each encoder count ([`crate::conditions::reacts_to_counts`]).
    reacts_to_counts: bool,
    kin: Kinematics,
    /// Used window `[lo, hi)`: steady running, away from the filter's start-up.
    lo: usize,
    hi: usize,
    /// Mean speed over the window, rad/s.
    speed: f64,
    /// Electrical periods over the window.
    periods: f64,
    /// Encoder steps against the direction of travel in the window, and all steps.
    back_steps: usize,
    steps: usize,
}

fn prepare<'a>(log: &'a RunLog, o: &FitOptions, kmax: u16) -> Result<Prepared<'a>, FitError> {
    let n = log.len();
    let nr = f64::from(o.pole_pairs);
    let (_, _, w_all) = kinematics::line_fit(&log.t_s, &log.theta_fb_rad);
    let too_short = |needed: usize| FitError::TooShort {
        log: log.source.clone(),
        samples: n,
        duration_s: log.duration_s(),
        speed: w_all,
        needed,
    };
    if n < MIN_STEADY_SAMPLES {
        return Err(too_short(MIN_STEADY_SAMPLES));
    }
    let moved = w_all.abs() * log.duration_s() * nr;
    if !moved.is_finite() {
        return Err(FitError::NonFinite {
            what: "the mean speed".into(),
            logs: log.source.clone(),
            detail: format!("duration {:.3e} s, mean speed {w_all:.3e} rad/s", log.duration_s()),
        });
    }
    if moved <= TAU {
        return Err(FitError::NoMotion { log: log.source.clone(), speed: w_all, periods: moved / TAU });
    }
    let ts = kinematics::median_step(&log.t_s);
    let fc = kinematics::corner_hz(w_all, o.counts_per_rev, kmax, o.pole_pairs, 1.0 / ts);
    let edges = o.correct_quantisation.then(|| crate::stick::edge_timed_angle(&log.t_s, &log.theta_fb_rad));
    let theta = edges.as_ref().map_or_else(|| log.theta_fb_rad.clone(), |e| e.theta_rad.clone());
    let kin = kinematics::estimate(&log.t_s, &theta, fc);
    // Steady window: from the first to the last sample running at ≥ 80 % of the mean speed
    // in its direction (drops the start from rest, the ramp and a final stop).
    let running = |i: &usize| kin.omega_rad_s[*i] * w_all.signum() >= 0.8 * w_all.abs();
    let (e0, e1) = (kin.edge.min(n), n.saturating_sub(kin.edge));
    if e1 < e0 + MIN_STEADY_SAMPLES {
        return Err(too_short(2 * kin.edge + MIN_STEADY_SAMPLES));
    }
    let lo = (e0..e1).find(running);
    let hi = (e0..e1).rev().find(running).map(|i| i + 1);
    let (lo, hi) = match (lo, hi) {
        (Some(a), Some(b)) if b >= a + MIN_STEADY_SAMPLES => (a, b),
        (a, b) => {
            let steady = match (a, b) {
                (Some(a), Some(b)) => b.saturating_sub(a),
                _ => 0,
            };
            return Err(FitError::Unsteady { log: log.source.clone(), speed: w_all, steady });
        }
    };
    let (_, _, speed) = kinematics::line_fit(&log.t_s[lo..hi], &log.theta_fb_rad[lo..hi]);
    let periods = nr * (log.theta_fb_rad[hi - 1] - log.theta_fb_rad[lo]).abs() / TAU;
    let (mut back_steps, mut steps) = (0, 0);
    for w in log.theta_fb_rad[lo..hi].windows(2) {
        let d = w[1] - w[0];
        if d != 0.0 {
            steps += 1;
            if d * speed < 0.0 {
                back_steps += 1;
            }
        }
    }
    let reacts_to_counts = edges.as_ref().is_some_and(|e| {
        let mean = log.i_q_a[lo..hi].iter().sum::<f64>() / (hi - lo) as f64 * speed.signum();
        crate::conditions::reacts_to_counts(crate::stick::count_rise(e, &log.i_q_a, lo, hi, speed.signum()), mean)
    });
    let keep = edges
        .map_or_else(|| vec![true; n], |e| crate::stick::moving_mask(&e, speed, kin.corner_hz, 1.0 / ts, &o.stick));
    Ok(Prepared { log, theta, keep, reacts_to_counts, kin, lo, hi, speed, periods, back_steps, steps })
}

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
    let mut prepared = logs.iter().map(|l| prepare(l, o, kmax)).collect::<Result<Vec<_>, _>>()?;
    // Hook (crate::conditions): slow runs short of friction are left out.
    let speeds: Vec<f64> = prepared.iter().map(|p| p.speed).collect();
    let held = FitOptions { fit_inertia: false, ..o.clone() };
    let reacts: Vec<bool> = prepared.iter().map(|p| p.reacts_to_counts).collect();
    let left_out = crate::conditions::slow_levels_to_leave_out(&speeds, &reacts, |runs| {
        let sub: Vec<Prepared> = runs.iter().map(|&i| prepared[i].clone()).collect();
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
    // Hook (crate::conditions): fit J or hold the base's, and say which.
    let speeds: Vec<f64> = prepared.iter().map(|p| p.speed).collect();
    let choice = crate::conditions::inertia_choice(o.fit_inertia, o.inertia, &speeds);
    let mut f = two_passes(&prepared, &FitOptions { fit_inertia: choice.is_ok(), ..o.clone() })?;
    let decision = match (choice, f.inertia_kg_m2) {
        (Ok(forced), Some(j)) if forced || j.ci95 <= crate::conditions::MAX_INERTIA_INTERVAL * j.value => {
            crate::conditions::Decision::InertiaFitted { value: j.value, ci95: j.ci95, forced }
        }
        (Ok(_), Some(j)) => {
            f = two_passes(&prepared, &held)?;
            let reason =
                format!("its interval ±{:.0} % is wide (the fit gave {:.4e} kg·m²)", 100.0 * j.ci95 / j.value, j.value);
            crate::conditions::Decision::InertiaHeld { base: o.inertia_kg_m2, reason }
        }
        (Err(reason), _) => crate::conditions::Decision::InertiaHeld { base: o.inertia_kg_m2, reason },
        (Ok(_), None) => {
            crate::conditions::Decision::InertiaHeld { base: o.inertia_kg_m2, reason: "not fitted".into() }
        }
    };
    f.warnings.splice(0..0, condition);
    f.decisions.push(decision);
    Ok(f)
}

fn two_passes(prepared: &[Prepared], o: &FitOptions) -> Result<Fit, FitError> {
    let first = fit_prepared(prepared, o, o.viscous_fallback_nm_s_per_rad)?;
    match first.viscous_nm_s_per_rad {
        Some(d) => fit_prepared(prepared, o, d.value.max(0.0)),
        None => Ok(first),
    }
}

fn fit_prepared(prepared: &[Prepared], o: &FitOptions, d_ripple: f64) -> Result<Fit, FitError> {
    let nr = f64::from(o.pole_pairs);
    let kmax = *o.orders.iter().max().expect("checked non-empty");

    // Which terms the data can separate.
    let mut warnings = Vec::new();
    let (mut fwd_periods, mut rev_periods) = (0.0, 0.0);
    for p in prepared {
        if p.speed > 0.0 {
            fwd_periods += p.periods;
        } else {
            rev_periods += p.periods;
        }
    }
    let one_direction = match (fwd_periods > 0.0, rev_periods > 0.0) {
        (true, true) => None,
        (true, false) => Some("forward"),
        _ => Some("reverse"),
    };
    if let Some(direction) = one_direction {
        warnings.push(Warning::OneDirection { direction });
    }
    for (dir, per) in [("forward", fwd_periods), ("reverse", rev_periods)] {
        if per > 0.0 && per < o.recommended_periods {
            warnings.push(Warning::FewPeriods { direction: dir, periods: per, recommended: o.recommended_periods });
        }
    }
    let terms = friction_terms(prepared, o.viscous_fallback_nm_s_per_rad);
    let (fit_d, both) = (terms.fit_d, terms.fit_c);
    warnings.extend(terms.warning);

    // Columns: a_k, b_k per order; Fs; [D]; [c]; [J].
    let nh = o.orders.len();
    let col_fs = 2 * nh;
    let col_d = fit_d.then_some(col_fs + 1);
    let col_c = both.then_some(col_fs + 1 + usize::from(fit_d));
    let col_j = o.fit_inertia.then_some(col_fs + 1 + usize::from(fit_d) + usize::from(both));
    let p = col_fs + 1 + usize::from(fit_d) + usize::from(both) + usize::from(o.fit_inertia);
    let total: usize = prepared.iter().map(|p| p.hi - p.lo).sum();
    let mut design = Design::new(p);
    design.x.reserve(total * p);
    design.y.reserve(total);
    design.block.reserve(total);
    let mut theta_e_used = Vec::with_capacity(total);
    // dω/dt of each used sample (the inertial torque is J times it).
    let mut alpha_used = Vec::with_capacity(total);
    let mut row = vec![0.0; p];
    let mut block_base = 0u32;
    let mut runs = Vec::new();
    let d_fixed = if fit_d { 0.0 } else { o.viscous_fallback_nm_s_per_rad };
    let logs_named = || prepared.iter().map(|p| p.log.source.as_str()).collect::<Vec<_>>().join(", ");
    let non_finite =
        |what: String| FitError::NonFinite { what, logs: logs_named(), detail: largest_effort(prepared, o) };
    for prep in prepared {
        let (log, kin) = (prep.log, &prep.kin);
        let effort = match o.effort {
            Effort::MeasuredIq => &log.i_q_a,
            Effort::CommandIq => log.iq_cmd_a.as_ref().ok_or_else(|| {
                FitError::Options(format!("{}: no iq_cmd_a column, needed for the command effort", log.source))
            })?,
        };
        // The effort through the filter `dω/dt` went through (see the module documentation,
        // *Inertia*).
        // The harmonics in it are scaled by the filter's gain at their frequency (≥ 0.998 by
        // the choice of the corner), and so are their regressors.
        let wbar = prep.speed;
        let smoothed;
        let mut harmonic_gain = vec![1.0; o.orders.len()];
        let effort = if o.smooth_effort {
            let mut v = effort.clone();
            let (fs, fc) = kinematics::smooth(&log.t_s, &mut v, kin.corner_hz);
            for (g, &k) in harmonic_gain.iter_mut().zip(&o.orders) {
                *g = kinematics::smooth_gain(f64::from(k) * nr * wbar.abs() / TAU, fc, fs);
            }
            smoothed = v;
            &smoothed
        } else {
            effort
        };
        let vmin = o.min_speed_fraction * wbar.abs();
        // Blocks of one electrical period (at least 10 blocks per log).
        let span = (log.theta_fb_rad[prep.hi - 1] - log.theta_fb_rad[prep.lo]).abs();
        let per_block = if prep.periods >= 10.0 { TAU / nr } else { span / 10.0 }.max(f64::MIN_POSITIVE);
        let th0 = log.theta_fb_rad[prep.lo];
        // The instrument for J: the part of dω/dt periodic in the fitted orders, this log's
        // own (see the module documentation, *Inertia*).
        let alpha_periodic = if col_j.is_some() { periodic_part(prep, &o.orders, nr) } else { None };
        let (mut used, mut stalled, mut max_block) = (0usize, 0usize, 0u32);
        #[allow(clippy::needless_range_loop)] // five parallel arrays are read at i
        for i in prep.lo..prep.hi {
            let w = kin.omega_rad_s[i];
            if w * wbar.signum() < vmin || !prep.keep[i] {
                stalled += 1;
                continue;
            }
            let th = prep.theta[i];
            let te = nr * th;
            let (s1, c1) = te.sin_cos();
            for (j, &k) in o.orders.iter().enumerate() {
                let (s, c) = if k == 1 { (s1, c1) } else { (f64::from(k) * te).sin_cos() };
                row[2 * j] = s * harmonic_gain[j];
                row[2 * j + 1] = c * harmonic_gain[j];
            }
            row[col_fs] = wbar.signum();
            if let Some(cd) = col_d {
                row[cd] = wbar;
            }
            if let Some(cc) = col_c {
                row[cc] = 1.0;
            }
            let alpha = kin.alpha_rad_s2[i];
            let j_alpha = match col_j {
                Some(cj) => {
                    row[cj] = alpha_periodic.as_ref().map_or(0.0, |c| c.at(te));
                    0.0
                }
                None => o.inertia_kg_m2 * alpha,
            };
            let y = o.km_nm_per_a * effort[i] - j_alpha - d_ripple * (w - wbar) - d_fixed * wbar;
            if !(y.is_finite() && alpha.is_finite()) {
                return Err(non_finite(format!("{}: the torque Km·i − J·dω/dt at t = {} s", log.source, log.t_s[i])));
            }
            let b = ((th - th0).abs() / per_block) as u32;
            max_block = max_block.max(b);
            design.push(&row, y, block_base + b);
            theta_e_used.push(te.rem_euclid(TAU));
            alpha_used.push(alpha);
            used += 1;
        }
        block_base += max_block + 1;
        let considered = (prep.hi - prep.lo).max(1);
        let fraction = stalled as f64 / considered as f64;
        if fraction > 0.02 {
            warnings.push(Warning::Stalled { source: log.source.clone(), fraction });
        }
        let back = prep.back_steps as f64 / prep.steps.max(1) as f64;
        if back > o.max_back_step_fraction {
            warnings.push(Warning::Reversing { source: log.source.clone(), fraction: back });
        }
        let highest_harmonic_hz = f64::from(kmax) * nr * wbar.abs() / TAU;
        if let (Some(bw), Some(cpr)) = (o.servo_bandwidth_hz, o.counts_per_rev) {
            let count_rate = f64::from(cpr) * wbar.abs() / TAU;
            if count_rate < 0.7 * TAU * bw {
                warnings.push(Warning::SlowForEncoder {
                    source: log.source.clone(),
                    count_rate_hz: count_rate,
                    needed_hz: TAU * bw,
                });
            }
        }
        if let Some(bw) = o.servo_bandwidth_hz
            && highest_harmonic_hz > 0.8 * bw
        {
            warnings.push(Warning::TooFast {
                source: log.source.clone(),
                order: kmax,
                harmonic_hz: highest_harmonic_hz,
                bandwidth_hz: bw,
            });
        }
        runs.push(RunSummary {
            source: log.source.clone(),
            mean_speed_rad_s: wbar,
            duration_s: log.t_s[prep.hi - 1] - log.t_s[prep.lo],
            electrical_periods: prep.periods,
            samples_used: used,
            samples: log.len(),
            highest_harmonic_hz,
            inertial_share: 0.0,
            back_step_fraction: back,
        });
    }
    let sol = match lsq::solve(&design) {
        Ok(sol) => sol,
        Err(LsqError::NonFinite(what)) => return Err(non_finite(what.to_string())),
        Err(e) => return Err(e.into()),
    };
    if let Some(what) = non_finite_in(&sol) {
        return Err(non_finite(what.to_string()));
    }

    // Quantisation correction of the harmonic regressors.
    let gain = |k: u16| match o.counts_per_rev {
        // The edge-timed angle (used whenever the correction is asked for) is not averaged
        // over a count: no correction needed.
        Some(cpr) if o.correct_quantisation && !EDGE_TIMED_ANGLE => sinc(f64::from(k) * PI * nr / f64::from(cpr)),
        _ => 1.0,
    };
    let mut harmonics = Vec::with_capacity(nh);
    for (j, &k) in o.orders.iter().enumerate() {
        let g = gain(k);
        let (a, b) = (sol.beta[2 * j] / g, sol.beta[2 * j + 1] / g);
        let g2 = g * g;
        let (vaa, vab, vbb) =
            (sol.cov[(2 * j, 2 * j)] / g2, sol.cov[(2 * j, 2 * j + 1)] / g2, sol.cov[(2 * j + 1, 2 * j + 1)] / g2);
        let (amplitude, phase) = polar_with_ci(a, b, vaa, vab, vbb);
        if amplitude.value < amplitude.ci95 {
            warnings.push(Warning::NotSignificant { order: k });
        }
        harmonics.push(HarmonicEstimate { order: k, amplitude_nm: amplitude, phase_rad: phase, a_nm: a, b_nm: b });
    }
    let est = |c: usize| Estimate { value: sol.beta[c], ci95: 1.96 * sol.cov[(c, c)].max(0.0).sqrt() };
    let coulomb = est(col_fs);
    let viscous = col_d.map(est);
    let offset = col_c.map(est);
    let inertia = col_j.map(est);
    let inertia_used = inertia.map_or(o.inertia_kg_m2, |j| j.value);
    let finite = |e: &Estimate| e.value.is_finite() && e.ci95.is_finite();
    if !harmonics.iter().all(|h| finite(&h.amplitude_nm) && finite(&h.phase_rad)) {
        return Err(non_finite("a harmonic amplitude or its interval".into()));
    }
    if !(finite(&coulomb) && viscous.iter().chain(&offset).all(finite)) {
        return Err(non_finite("a friction term or its interval".into()));
    }
    if !inertia.iter().all(finite) {
        return Err(non_finite("the inertia or its interval".into()));
    }
    if let Some(j) = inertia {
        if !(j.value > 0.0 && j.ci95 < o.max_inertia_disagreement * j.value) {
            warnings.push(Warning::InertiaUncertain { value: j.value, ci95: j.ci95 });
        } else if o.inertia_kg_m2 > 0.0 && (j.value / o.inertia_kg_m2 - 1.0).abs() > o.max_inertia_disagreement {
            warnings.push(Warning::InertiaDisagrees { value: j.value, ci95: j.ci95, base: o.inertia_kg_m2 });
        }
    }
    if coulomb.value < coulomb.ci95 {
        warnings.push(Warning::CoulombNotPositive {
            value_nm: coulomb.value,
            ci95_nm: coulomb.ci95,
            one_direction,
            viscous_held: (!fit_d).then_some(o.viscous_fallback_nm_s_per_rad),
        });
    }
    if let Some(d) = viscous
        && d.value < 0.0
    {
        warnings.push(Warning::ViscousNegative { value: d.value, ci95: d.ci95 });
    }
    for (c, name) in [(Some(col_fs), "Fs"), (col_d, "D"), (col_c, "the constant torque"), (col_j, "J")] {
        if let Some(c) = c
            && sol.inflation[c] > o.max_inflation
        {
            warnings.push(Warning::Confounded { term: name.to_string(), inflation: sol.inflation[c] });
        }
    }
    for (j, &k) in o.orders.iter().enumerate() {
        let inf = sol.inflation[2 * j].max(sol.inflation[2 * j + 1]);
        if inf > o.max_inflation {
            warnings.push(Warning::Confounded { term: format!("harmonic {k}"), inflation: inf });
        }
    }

    // Periodic part and per-log inertial share.
    let mut ripple = Vec::with_capacity(sol.residual.len());
    let mut fitted_ss = 0.0;
    let mut start = 0;
    for run in runs.iter_mut() {
        let (mut s_inertial, mut s_fit) = (0.0, 0.0);
        #[allow(clippy::needless_range_loop)] // three parallel arrays are read at i
        for i in start..start + run.samples_used {
            let xrow = &design.x[i * p..(i + 1) * p];
            let fitted: f64 = (0..2 * nh).map(|c| xrow[c] * sol.beta[c]).sum();
            ripple.push(fitted + sol.residual[i]);
            let j_alpha = inertia_used * alpha_used[i];
            s_inertial += j_alpha * j_alpha;
            s_fit += fitted * fitted;
        }
        fitted_ss += s_fit;
        run.inertial_share = if s_fit > 0.0 { (s_inertial / s_fit).sqrt() } else { 0.0 };
        if run.inertial_share > o.max_inertial_share {
            warnings.push(Warning::InertialShare { source: run.source.clone(), share: run.inertial_share });
        }
        start += run.samples_used;
    }
    let ripple_rms_nm = (fitted_ss / ripple.len().max(1) as f64).sqrt();
    if !ripple_rms_nm.is_finite() {
        return Err(non_finite("the fitted detent ripple".into()));
    }
    Ok(Fit {
        harmonics,
        coulomb_friction_nm: coulomb,
        viscous_used: viscous.map_or(o.viscous_fallback_nm_s_per_rad, |v| v.value),
        viscous_nm_s_per_rad: viscous,
        offset_nm: offset,
        inertia_kg_m2: inertia,
        inertia_used,
        residual_rms_nm: sol.residual_rms,
        ripple_rms_nm,
        samples_used: sol.residual.len(),
        condition: sol.condition,
        runs,
        warnings,
        decisions: Vec::new(),
        samples: FitSamples { theta_e_rad: theta_e_used, ripple_nm: ripple, residual_nm: sol.residual },
    })
}

/// Fourier coefficients (sin, cos per order, then the mean) of a log's `dω/dt` against the
/// electrical angle over its used window.
struct Periodic {
    orders: Vec<u16>,
    coef: Vec<f64>,
}

impl Periodic {
    fn at(&self, te: f64) -> f64 {
        let mut v = self.coef[2 * self.orders.len()];
        for (j, &k) in self.orders.iter().enumerate() {
            let (s, c) = (f64::from(k) * te).sin_cos();
            v += self.coef[2 * j] * s + self.coef[2 * j + 1] * c;
        }
        v
    }
}

/// The least-squares fit of `dω/dt` over the window of `prep` on `sin, cos(k·Nr·θ_fb)` of
/// `orders` and a constant; `None` when it cannot be solved.
fn periodic_part(prep: &Prepared, orders: &[u16], nr: f64) -> Option<Periodic> {
    let m = 2 * orders.len() + 1;
    let mut ata = nalgebra::DMatrix::<f64>::zeros(m, m);
    let mut atb = nalgebra::DVector::<f64>::zeros(m);
    let mut row = vec![0.0; m];
    for i in (prep.lo..prep.hi).filter(|&i| prep.keep[i]) {
        let te = nr * prep.theta[i];
        for (j, &k) in orders.iter().enumerate() {
            let (s, c) = (f64::from(k) * te).sin_cos();
            row[2 * j] = s;
            row[2 * j + 1] = c;
        }
        row[m - 1] = 1.0;
        let a = prep.kin.alpha_rad_s2[i];
        for r in 0..m {
            atb[r] += row[r] * a;
            for c in r..m {
                ata[(r, c)] += row[r] * row[c];
            }
        }
    }
    for r in 0..m {
        for c in 0..r {
            ata[(r, c)] = ata[(c, r)];
        }
    }
    let coef = ata.cholesky()?.solve(&atb);
    coef.iter()
        .all(|v| v.is_finite())
        .then(|| Periodic { orders: orders.to_vec(), coef: coef.iter().copied().collect() })
}

/// The friction and constant terms the logs' levels (direction, `|ω̄|`) can separate, and
/// the warning for the term held (see the module documentation, *Friction terms*).
struct FrictionTerms {
    fit_d: bool,
    fit_c: bool,
    warning: Option<Warning>,
}

fn friction_terms(prepared: &[Prepared], viscous_fallback: f64) -> FrictionTerms {
    // (min, max, mean) of |ω̄| over the logs of one direction.
    let range = |forward: bool| {
        let speeds: Vec<f64> = prepared.iter().filter(|p| (p.speed > 0.0) == forward).map(|p| p.speed.abs()).collect();
        (!speeds.is_empty()).then(|| {
            let (lo, hi) = speeds.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
            (lo, hi, speeds.iter().sum::<f64>() / speeds.len() as f64)
        })
    };
    let two_speeds = |r: Option<(f64, f64, f64)>| r.is_some_and(|(lo, hi, _)| hi >= SPEED_RATIO * lo);
    let (fwd, rev) = (range(true), range(false));
    let fit_d = two_speeds(fwd) || two_speeds(rev);
    let fit_c = fwd.is_some() && rev.is_some();
    let warning = if fit_d {
        None
    } else {
        match (fwd, rev) {
            (Some((f0, f1, fm)), Some((r0, r1, rm))) if f1.max(r1) >= SPEED_RATIO * f0.min(r0) => {
                // One speed per direction, different: the extreme pair spans the directions.
                // Adding the faster speed in the slower direction separates D.
                let add_run = if r1 / f0 >= f1 / r0 { ("forward", r1) } else { ("reverse", f1) };
                Some(Warning::OneSpeedPerDirection {
                    forward_rad_s: fm,
                    reverse_rad_s: rm,
                    viscous_used: viscous_fallback,
                    add_run,
                })
            }
            _ => {
                let smax = fwd.iter().chain(&rev).map(|r| r.1).fold(0.0, f64::max);
                Some(Warning::SingleSpeed { speed_rad_s: smax, viscous_used: viscous_fallback })
            }
        }
    };
    FrictionTerms { fit_d, fit_c, warning }
}

/// The first part of a least-squares solution that is not finite: a coefficient, the
/// covariance (it gives every interval) or the residual.
fn non_finite_in(sol: &lsq::Solution) -> Option<&'static str> {
    if sol.beta.iter().any(|b| !b.is_finite()) {
        Some("a coefficient")
    } else if sol.cov.iter().any(|c| !c.is_finite()) {
        Some("the covariance")
    } else if !sol.residual_rms.is_finite() || sol.residual.iter().any(|e| !e.is_finite()) {
        Some("the residual")
    } else {
        None
    }
}

/// Where the effort of the logs is largest in magnitude (or not a number), for errors.
fn largest_effort(prepared: &[Prepared], o: &FitOptions) -> String {
    let mut largest: Option<(f64, &str)> = None;
    for p in prepared {
        let effort = match o.effort {
            Effort::MeasuredIq => Some(&p.log.i_q_a),
            Effort::CommandIq => p.log.iq_cmd_a.as_ref(),
        };
        for &v in effort.into_iter().flatten() {
            if v.is_nan() {
                return format!("a current that is not a number in {}", p.log.source);
            }
            if largest.is_none_or(|(m, _)| v.abs() > m) {
                largest = Some((v.abs(), &p.log.source));
            }
        }
    }
    match largest {
        Some((m, src)) => format!("largest |current| {m:.3e} A, in {src}"),
        None => "no current samples".into(),
    }
}

/// Amplitude and phase of `a sin x + b cos x = A sin(x + φ)` with 95 % half-widths by the
/// delta method from the covariance `[[vaa, vab], [vab, vbb]]` of `(a, b)`.
pub fn polar_with_ci(a: f64, b: f64, vaa: f64, vab: f64, vbb: f64) -> (Estimate, Estimate) {
    let amp = a.hypot(b);
    let (sd_a, sd_p) = if amp > 0.0 {
        let (ga, gb) = (a / amp, b / amp);
        let (ha, hb) = (-b / (amp * amp), a / (amp * amp));
        (
            (ga * ga * vaa + 2.0 * ga * gb * vab + gb * gb * vbb).max(0.0).sqrt(),
            (ha * ha * vaa + 2.0 * ha * hb * vab + hb * hb * vbb).max(0.0).sqrt(),
        )
    } else {
        ((vaa + vbb).max(0.0).sqrt(), PI)
    };
    (Estimate { value: amp, ci95: 1.96 * sd_a }, Estimate { value: wrap_pi(b.atan2(a)), ci95: (1.96 * sd_p).min(PI) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_pi_maps_into_the_half_open_interval() {
        assert_eq!(wrap_pi(PI), PI);
        assert_eq!(wrap_pi(-PI), PI);
        assert!((wrap_pi(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_pi(0.3) - 0.3).abs() < 1e-15);
    }

    #[test]
    fn a_non_finite_coefficient_covariance_or_residual_is_caught_after_the_solve() {
        let ok = lsq::Solution {
            beta: vec![1.0, 2.0],
            cov: nalgebra::DMatrix::identity(2, 2),
            residual: vec![0.1, -0.1, 0.0],
            residual_rms: 0.08,
            condition: 1.0,
            inflation: vec![1.0, 1.0],
        };
        assert_eq!(non_finite_in(&ok), None);
        let mut s = ok.clone();
        s.cov[(1, 0)] = f64::NAN;
        assert_eq!(non_finite_in(&s), Some("the covariance"));
        let mut s = ok.clone();
        s.beta[0] = f64::INFINITY;
        assert_eq!(non_finite_in(&s), Some("a coefficient"));
        let mut s = ok;
        s.residual_rms = f64::INFINITY;
        assert_eq!(non_finite_in(&s), Some("the residual"));
    }
}
